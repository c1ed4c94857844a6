"""treecal: kinematic calibration of branched robots (torso + arms) described by URDF.

The Python face of the Rust library (``treecal::workflow``): one call per job, numpy in and
out, and one exception type, :class:`TreecalError`, whose message is the CLI's
``treecal: error:`` text. See docs/python.md.
"""

from __future__ import annotations

import collections.abc
import json
import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _treecal
from ._treecal import TreecalError

__all__ = [
    "Calibration",
    "Measurements",
    "TreecalError",
    "Verification",
    "calibrate",
    "compare",
    "fk",
    "verify",
    "__version__",
]

__version__: str = _treecal.__version__

PathLike = Union[str, "os.PathLike[str]"]

_OBSERVATION_WIDTH = {"positions": 3, "poses": 7, "targets": 9}


_SEED_MAX = 2**64 - 1


def _path(value: Any, name: str) -> str:
    """A path argument as a string (str or os.PathLike of str)."""
    try:
        path = os.fspath(value)
    except TypeError:
        raise TreecalError(f"{name}: expected a path (str or os.PathLike), got {type(value).__name__}") from None
    if not isinstance(path, str):
        raise TreecalError(f"{name}: expected a text path, got {type(path).__name__}")
    return path


def _robot_path(robot: Optional[PathLike]) -> Optional[str]:
    """The URDF path as a string, or None for the built-in Robonaut."""
    if robot is None:
        return None
    return _path(robot, "robot")


def _text(value: Any, name: str) -> str:
    """A str argument (no silent str() of other types: a typo'd object must not become text)."""
    if not isinstance(value, str):
        raise TreecalError(f"{name}: expected a str, got {type(value).__name__}")
    return value


def _optional_text(value: Any, name: str) -> Optional[str]:
    return None if value is None else _text(value, name)


def _float(value: Any, name: str) -> float:
    """A real number argument (bool is refused: True is not a sigma)."""
    if isinstance(value, bool):
        raise TreecalError(f"{name}: expected a number, got bool")
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError) as error:
        raise TreecalError(f"{name}: expected a number ({error})") from None


def _seed(value: Any) -> int:
    """The seed: an integer from 0 to 2**64 - 1."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TreecalError(f"seed: expected an integer, got {type(value).__name__}")
    if not 0 <= int(value) <= _SEED_MAX:
        raise TreecalError(f"seed: {value} is outside 0 … 2**64 - 1")
    return int(value)


def _flag(value: Any, name: str) -> bool:
    """A bool argument (0 and 1 accepted; "no" is not False)."""
    if isinstance(value, (bool, np.bool_)) or (isinstance(value, (int, np.integer)) and value in (0, 1)):
        return bool(value)
    raise TreecalError(f"{name}: expected True or False, got {value!r}")


def _native(call: Any, **arguments: Any) -> Any:
    """Calls the extension; an argument it cannot convert is a TreecalError, never a
    TypeError or OverflowError from inside."""
    try:
        return call(**arguments)
    except TreecalError:
        raise
    except (TypeError, OverflowError, ValueError) as error:
        raise TreecalError(f"invalid argument: {error}") from None


def _matrix(values: Any, name: str, width: Optional[int] = None) -> np.ndarray:
    """`values` as a finite-or-NaN float matrix (rows, columns), checked on the Python side
    only for its shape; the Rust side checks every value and names the row."""
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise TreecalError(f"{name}: not an array of numbers ({error})") from None
    if array.ndim == 1 and width is not None and array.shape[0] == width:
        array = array[None, :]
    if array.ndim != 2:
        raise TreecalError(f"{name}: expected a 2-D array (rows, columns), got shape {array.shape}")
    if width is not None and array.shape[1] != width:
        raise TreecalError(f"{name}: expected {width} columns per row, got {array.shape[1]}")
    return array


def _strings(values: Any, name: str, rows: Optional[int] = None) -> List[str]:
    """A list of str (one per row when `rows` is given)."""
    if isinstance(values, (str, bytes)):
        raise TreecalError(f"{name}: expected a sequence of strings, got one string")
    try:
        result = [str(v) for v in values]
    except TypeError:
        raise TreecalError(f"{name}: expected a sequence of strings, got {type(values).__name__}") from None
    if rows is not None and len(result) != rows:
        raise TreecalError(f"{name}: {len(result)} entries for {rows} rows")
    return result


def _unique(names: List[str], name: str) -> None:
    """Each joint named once: a repeated name would take one column's values silently."""
    seen: Dict[str, int] = {}
    for index, joint in enumerate(names):
        key = joint.strip()
        if key in seen:
            raise TreecalError(
                f"{name}: joint '{key}' is named twice (entries {seen[key] + 1} and {index + 1}); name each joint once"
            )
        seen[key] = index


#: Rows per call of the native `fk` (`fk` passes longer tables in chunks of this many rows).
_FK_CHUNK_ROWS = 65536


def fk(
    robot: Optional[PathLike],
    tip: str,
    joints: Union[Mapping[str, float], Any],
    joint_names: Optional[Sequence[str]] = None,
    angle_unit: str = "rad",
) -> np.ndarray:
    """The pose ``root_from_tip`` of link `tip` (4x4 homogeneous matrices, metres).

    `robot` is a URDF path, or None for the built-in Robonaut. `joints` is either an (N, k)
    array whose columns `joint_names` names (result (N, 4, 4)), or a dict {joint: value} for
    one configuration (result (4, 4); so is a 1-D array of k values). Joints not given are 0; revolute values are in
    `angle_unit` ("rad" or "deg"), prismatic ones in metres. Rows are the same as
    ``treecal fk`` prints for a joints CSV with these columns.
    """
    single = isinstance(joints, collections.abc.Mapping)
    if single:
        if joint_names is not None:
            raise TreecalError("fk: joint_names is for an array of joints; a dict names its joints itself")
        names = [str(k) for k in joints.keys()]
        rows = _matrix([[_float(v, f"joints['{k}']") for k, v in joints.items()]], "joints")
    else:
        if joint_names is None:
            raise TreecalError("fk: joint_names is required when joints is an array")
        names = _strings(joint_names, "joint_names")
        _unique(names, "joint_names")
        try:
            array = np.asarray(joints, dtype=np.float64)
        except (TypeError, ValueError) as error:
            raise TreecalError(f"joints: not an array of numbers ({error})") from None
        single = array.ndim == 1
        rows = _matrix(array[None, :] if single else array, "joints")
        if rows.shape[1] != len(names):
            raise TreecalError(
                f"fk: joints has {rows.shape[1]} columns but joint_names names {len(names)}"
            )
    # In chunks: only one chunk's rows exist as Python lists at a time (a 10⁷-row table as one
    # list of lists took 12.6 GiB); the result is written into one preallocated array.
    poses = np.empty((rows.shape[0], 4, 4), dtype=np.float64)
    for start in range(0, max(rows.shape[0], 1), _FK_CHUNK_ROWS):
        chunk = rows[start : start + _FK_CHUNK_ROWS]
        flat = _native(
            _treecal.fk,
            robot=_robot_path(robot),
            tip=_text(tip, "tip"),
            joint_names=names,
            joints=chunk.tolist(),
            angle_unit=_text(angle_unit, "angle_unit"),
            first_row=start,
        )
        poses[start : start + chunk.shape[0]] = np.asarray(flat, dtype=np.float64).reshape(-1, 4, 4)
    return poses[0] if single else poses


class Measurements:
    """A measurement table from arrays: the same rows a measurement CSV holds.

    One row per tool observation: `tools[i]` is the measured tool link, `joints[i]` the joint
    values (columns named by `joint_names`; NaN = not given), and exactly one of

    - `positions` (N, 3): x, y, z of the tool;
    - `poses` (N, 7): x, y, z, qw, qx, qy, qz of the tool frame;
    - `targets` (N, 9): three targets A, B, C (ax, ay, az, bx, …, cz) on the tool.

    `ids` name the rows in messages and reports (default "1".."N"); `stages` label rows
    "torso" or "arms" for the staged plan; `sessions` name each row's measurement session
    (one measurement frame per session, the CSV's `session` column); `points` name the
    measured point of each row on its tool (several markers on one body, the CSV's `point`
    column). `length_unit` ("m"/"mm") and `angle_unit`
    ("rad"/"deg") are the units of the values, like a CSV's ``# units:`` comment (default:
    m and rad, with the same diagnoses of a wrong unit as for a CSV). Values are checked by
    the same code that reads a CSV, when the table is used; errors name the row id.
    """

    def __init__(
        self,
        tools: Sequence[str],
        joints: Any,
        joint_names: Sequence[str],
        *,
        positions: Any = None,
        poses: Any = None,
        targets: Any = None,
        ids: Optional[Sequence[Any]] = None,
        stages: Optional[Sequence[str]] = None,
        sessions: Optional[Sequence[str]] = None,
        points: Optional[Sequence[str]] = None,
        length_unit: Optional[str] = None,
        angle_unit: Optional[str] = None,
        origin: str = "measurements (arrays)",
    ) -> None:
        given = [(k, v) for k, v in (("positions", positions), ("poses", poses), ("targets", targets)) if v is not None]
        if len(given) != 1:
            raise TreecalError(
                f"{origin}: give exactly one of positions= (N,3), poses= (N,7) or targets= (N,9)"
            )
        self.kind, observed = given[0]
        self.observations = _matrix(observed, f"{origin}: {self.kind}", _OBSERVATION_WIDTH[self.kind])
        rows = self.observations.shape[0]
        self.joint_names = _strings(joint_names, f"{origin}: joint_names")
        _unique(self.joint_names, f"{origin}: joint_names")
        self.joints = _matrix(joints, f"{origin}: joints", len(self.joint_names))
        if self.joints.shape[0] != rows:
            raise TreecalError(f"{origin}: joints has {self.joints.shape[0]} rows but {self.kind} has {rows}")
        self.tools = _strings(tools, f"{origin}: tools", rows)
        self.ids = None if ids is None else _strings(ids, f"{origin}: ids", rows)
        self.stages = None if stages is None else _strings(stages, f"{origin}: stages", rows)
        self.sessions = None if sessions is None else _strings(sessions, f"{origin}: sessions", rows)
        self.points = None if points is None else _strings(points, f"{origin}: points", rows)
        self.length_unit = _optional_text(length_unit, "length_unit")
        self.angle_unit = _optional_text(angle_unit, "angle_unit")
        self.origin = _text(origin, "origin")

    def __len__(self) -> int:
        return int(self.observations.shape[0])

    def __repr__(self) -> str:
        return f"Measurements({len(self)} rows of {self.kind}, {len(self.joint_names)} joints, origin={self.origin!r})"

    def _payload(self) -> Dict[str, Any]:
        """Plain lists for the Rust side (treecal::io::MeasurementTable)."""
        return {
            "origin": self.origin,
            "ids": self.ids,
            "tools": self.tools,
            "joint_names": self.joint_names,
            "joints": self.joints.tolist(),
            "kind": self.kind,
            "observations": self.observations.tolist(),
            "stages": self.stages,
            "sessions": self.sessions,
            "points": self.points,
            "length_unit": self.length_unit,
            "angle_unit": self.angle_unit,
        }


MeasurementsLike = Union[PathLike, Sequence[PathLike], Measurements]


def _measurement_source(value: Optional[MeasurementsLike], name: str) -> Any:
    """A CSV path (str) or a Measurements payload (dict) for the Rust side."""
    if value is None:
        return None
    if isinstance(value, Measurements):
        return value._payload()
    if isinstance(value, (str, os.PathLike)):
        return _path(value, name)
    if isinstance(value, (list, tuple)) and value and all(
        isinstance(v, (str, os.PathLike)) for v in value
    ):
        # Several CSVs, read as one set, each file its own session (the CLI's repeated flag).
        return [_path(v, name) for v in value]
    raise TreecalError(
        f"{name}: expected a CSV path, a list of CSV paths or treecal.Measurements, "
        f"got {type(value).__name__}"
    )


class Calibration:
    """The outcome of :func:`calibrate` (the CLI's ``out/calibrate`` directory, in memory).

    A failed verdict is not an exception: check :attr:`verdict` (``"ok"``, ``"warning"`` or
    ``"failed"``) and :attr:`reasons`.
    """

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        verdict = json.loads(inner.verdict_json)
        #: "ok", "warning" or "failed" (failed: do not use the result).
        self.verdict: str = verdict["status"]
        #: Every finding in the order the checks ran: dicts with status, code, message.
        self.reasons: List[Dict[str, str]] = verdict["reasons"]
        #: What the CLI prints on stderr: (level, text) with level note, warning or error.
        self.notes: List[Tuple[str, str]] = [(str(level), str(text)) for level, text in inner.notes]
        #: One dict per parameter: name, owner, kind, unit, nominal, calibrated, change,
        #: std_dev, identifiable.
        self.parameters: List[Dict[str, Any]] = json.loads(inner.parameters_json)
        #: The content of report.json.
        self.report: Dict[str, Any] = json.loads(inner.report_json)
        #: report.md.
        self.markdown: str = inner.markdown
        #: calibrated.urdf, or None when the verdict failed or the export was impossible.
        self.urdf: Optional[str] = inner.urdf

    @property
    def usable(self) -> bool:
        """Whether the result may be used (verdict ok or warning)."""
        return self.verdict != "failed"

    @property
    def files(self) -> Dict[str, bytes]:
        """Every output file the CLI writes, by name."""
        return dict(self._inner.files())

    def write_urdf(self, path: PathLike) -> None:
        """Writes the calibrated URDF; raises TreecalError when there is none (failed verdict)."""
        if self.urdf is None:
            why = "; ".join(r["message"] for r in self.reasons if r["status"] == "failed")
            raise TreecalError(
                f"no calibrated URDF: the verdict is {self.verdict}" + (f" ({why})" if why else "")
            )
        self._inner.write_urdf(_path(path, "path"))

    def write(self, out_dir: PathLike) -> None:
        """Writes every output file into `out_dir` (created), like ``treecal calibrate --out``."""
        self._inner.write(_path(out_dir, "out_dir"))

    def __repr__(self) -> str:
        return f"Calibration(verdict={self.verdict!r}, {len(self.parameters)} parameters)"


def calibrate(
    robot: Optional[PathLike] = None,
    measurements: Optional[MeasurementsLike] = None,
    validation: Optional[MeasurementsLike] = None,
    *,
    length_unit: Optional[str] = None,
    angle_unit: Optional[str] = None,
    joint_length_unit: Optional[str] = None,
    stiffness: Optional[PathLike] = None,
    tools: Optional[Sequence[str]] = None,
    reference_link: Optional[str] = None,
    plan: Optional[PathLike] = None,
    seed: int = 0,
    robust: str = "huber",
    identify_stiffness: bool = False,
    stiffness_prior: Optional[float] = None,
    measurement_frame: PathLike = "auto",
    gravity_frame: str = "measurement",
    position_sigma: Optional[float] = None,
    rotation_sigma: Optional[float] = None,
    ignore_columns: Sequence[str] = (),
    strict: bool = False,
    add_tool_links: bool = True,
    camera: Optional[PathLike] = None,
    detections: Optional[DetectionsLike] = None,
    pixel_sigma: float = 0.5,
    contacts: Optional[PathLike] = None,
    contact_setup: Optional[PathLike] = None,
    model: str = "adaptive",
    prior: bool = False,
    prior_scale: float = 1.0,
    cv: Optional[int] = None,
    freeze: Sequence[str] = (),
    free: Sequence[str] = (),
) -> Calibration:
    """Calibrates `robot` (URDF path; None: the built-in Robonaut) from `measurements`.

    The same job as ``treecal calibrate`` with the same defaults; keyword names are the CLI's
    flags. `measurements` and `validation` are a measurement CSV path, a list of them (read
    as one set, each file its own session unless its rows name one) or a
    :class:`Measurements`; without `validation` a seeded fifth is held out. `plan` is
    "staged", "simultaneous", a plan YAML path, or None (staged when rows are labelled
    torso/arms). `measurement_frame` is "auto", "fit", "base" or a registration YAML path;
    `robust` "huber", "cauchy" or "off"; `gravity_frame` "measurement" or "base".
    `reference_link` names the link fixed in the world while measuring (a sole, a mobile
    base; None: the URDF root).
    `position_sigma` (m), `rotation_sigma` (rad) and `stiffness_prior` default to the CLI's
    defaults (None). `model` ("adaptive", "offsets", "geometry", "auto"), `prior`,
    `prior_scale`, `cv` (folds) and `freeze` / `free` (parameter name patterns, as in
    params.yaml) are the CLI's model flags (docs/identification.md; with contacts
    docs/contacts.md, "The model the data support").
    Bad input raises :class:`TreecalError`; a failed verdict does not (see
    :attr:`Calibration.verdict`).

    With `camera` (a camera file: cameras and targets, docs/file-formats.md) the robot is
    calibrated from the pixels of `detections` (``treecal calibrate --camera``): a detections
    CSV path, or rows in memory (an iterable of mappings with the keys id, camera, target,
    corner, u, v and one per joint, radians and metres). `validation` is then a held-out
    detections CSV path, `measurements` optional tracker rows (a measurement CSV path) fitted
    with the pixels, each with its σ (`pixel_sigma` px, `position_sigma` m, `rotation_sigma`
    rad). The :class:`Calibration`'s parameters are then the robot's (name, nominal,
    calibrated, std_dev, determined) and its report the camera report (docs/camera.md).

    With `contacts` (a contacts CSV path) and `contact_setup` (its setup YAML) the robot is
    calibrated from contacts (``treecal calibrate --contacts``, docs/contacts.md): faces flush
    on a table, points on a plane, touches, a bar. `validation` is then a held-out contacts CSV
    path (default: every fifth row held out), `reference_link` overrides the setup's, and
    `measurements` optional tracker rows (a measurement CSV path) fitted with the contacts, each
    with its σ. The verdict is "ok" when the calibrated robot predicts the held-out contacts
    better than the registered nominal robot (calibrated.urdf written), else "failed"; the
    parameters are (name, value) and the report the contacts report.
    """
    if contacts is not None or contact_setup is not None:
        if camera is not None:
            raise TreecalError("calibrate: contacts with a camera file are not offered here yet; use the CLI")
        unused = [
            name
            for name, given in (
                ("stiffness", stiffness is not None),
                ("identify_stiffness", identify_stiffness),
                ("stiffness_prior", stiffness_prior is not None),
                ("plan", plan is not None),
            )
            if given
        ]
        if unused:
            raise TreecalError(
                f"calibrate: {', '.join(unused)} not used with contacts= (the contact calibration "
                "fits the setup's tools' joint frames, rigid, in one step); leave them out"
            )
        return _calibrate_contacts(
            robot, contacts, contact_setup, validation, reference_link, measurements,
            position_sigma, rotation_sigma, measurement_frame, length_unit, ignore_columns,
            _model_arguments(model, prior, prior_scale, cv, freeze, free), seed, tools,
        )
    if camera is not None:
        asked = _model_arguments(model, prior, prior_scale, cv, freeze, free)
        if asked != _model_arguments("adaptive", False, 1.0, None, (), ()):
            raise TreecalError(
                "calibrate: model, prior, prior_scale, cv, freeze and free are not used with camera= "
                "(the camera calibration fits its own model); leave them out"
            )
        return _calibrate_camera(
            robot, camera, detections, validation, measurements, pixel_sigma,
            position_sigma, rotation_sigma, measurement_frame, length_unit, angle_unit,
            joint_length_unit, tools, ignore_columns, add_tool_links,
        )
    if detections is not None:
        raise TreecalError("calibrate: detections= needs camera= (the camera file)")
    if measurements is None:
        raise TreecalError("calibrate: measurements= is required (a CSV path or treecal.Measurements)")
    inner = _native(
        _treecal.calibrate,
        robot=_robot_path(robot),
        measurements=_measurement_source(measurements, "measurements"),
        validation=_measurement_source(validation, "validation"),
        length_unit=_optional_text(length_unit, "length_unit"),
        angle_unit=_optional_text(angle_unit, "angle_unit"),
        joint_length_unit=_optional_text(joint_length_unit, "joint_length_unit"),
        stiffness=None if stiffness is None else _path(stiffness, "stiffness"),
        tools=None if tools is None else _strings(tools, "tools"),
        reference_link=_optional_text(reference_link, "reference_link"),
        plan=None if plan is None else _path(plan, "plan"),
        seed=_seed(seed),
        robust=_text(robust, "robust"),
        identify_stiffness=_flag(identify_stiffness, "identify_stiffness"),
        stiffness_prior=None if stiffness_prior is None else _float(stiffness_prior, "stiffness_prior"),
        measurement_frame=_path(measurement_frame, "measurement_frame"),
        gravity_frame=_text(gravity_frame, "gravity_frame"),
        position_sigma=None if position_sigma is None else _float(position_sigma, "position_sigma"),
        rotation_sigma=None if rotation_sigma is None else _float(rotation_sigma, "rotation_sigma"),
        ignore_columns=_strings(ignore_columns, "ignore_columns"),
        strict=_flag(strict, "strict"),
        add_tool_links=_flag(add_tool_links, "add_tool_links"),
        **_model_arguments(model, prior, prior_scale, cv, freeze, free),
    )
    return Calibration(inner)


def _model_arguments(
    model: Any, prior: Any, prior_scale: Any, cv: Any, freeze: Any, free: Any
) -> Dict[str, Any]:
    """The model keywords of `calibrate`, checked."""
    folds = None
    if cv is not None:
        if isinstance(cv, bool) or not isinstance(cv, int) or cv < 2:
            raise TreecalError(f"calibrate: cv must be a number of folds of at least 2, not {cv!r}")
        folds = cv
    scale = _float(prior_scale, "prior_scale")
    if not scale > 0.0:
        raise TreecalError(f"calibrate: prior_scale must be above 0, not {prior_scale!r}")
    return dict(
        model=_text(model, "model"),
        prior=_flag(prior, "prior"),
        prior_scale=scale,
        cv=folds,
        freeze=_strings(freeze, "freeze"),
        free=_strings(free, "free"),
    )


DetectionsLike = Union[PathLike, Sequence[Mapping[str, Any]]]


def _detections_csv(rows: Any) -> str:
    """Detection rows (mappings) as detections CSV text, columns in the first row's order."""
    if isinstance(rows, Mapping) or not isinstance(rows, collections.abc.Iterable):
        raise TreecalError("detections: give a CSV path or an iterable of row mappings")
    rows = list(rows)
    if not rows or not all(isinstance(r, Mapping) for r in rows):
        raise TreecalError("detections: give at least one row, each a mapping of column to value")
    columns = [str(c) for c in rows[0].keys()]
    lines = [",".join(columns)]
    for k, row in enumerate(rows):
        if set(map(str, row.keys())) != set(columns):
            raise TreecalError(f"detections: row {k} has other columns than row 0 ({', '.join(columns)})")
        lines.append(",".join(str(row[c]) if not isinstance(row[c], float) else repr(row[c]) for c in columns))
    return "\n".join(lines) + "\n"


def _calibrate_camera(
    robot: Any, camera: Any, detections: Any, validation: Any, measurements: Any,
    pixel_sigma: Any, position_sigma: Any, rotation_sigma: Any, measurement_frame: Any,
    length_unit: Any, angle_unit: Any, joint_length_unit: Any, tools: Any,
    ignore_columns: Any, add_tool_links: Any,
) -> "Calibration":
    """`calibrate` with a camera file (see there)."""
    if detections is None:
        raise TreecalError("calibrate: camera= needs detections= (a CSV path or rows)")
    as_path = isinstance(detections, (str, os.PathLike))
    for value, name in ((validation, "validation"), (measurements, "measurements")):
        if value is not None and not isinstance(value, (str, os.PathLike)):
            raise TreecalError(f"calibrate: with camera=, {name}= is a CSV path")
    inner = _native(
        _treecal.calibrate_camera,
        robot=_robot_path(robot),
        camera=_path(camera, "camera"),
        detections=_path(detections, "detections") if as_path else None,
        detections_csv=None if as_path else _detections_csv(detections),
        validation=None if validation is None else _path(validation, "validation"),
        measurements=None if measurements is None else _path(measurements, "measurements"),
        pixel_sigma=_float(pixel_sigma, "pixel_sigma"),
        position_sigma=None if position_sigma is None else _float(position_sigma, "position_sigma"),
        rotation_sigma=None if rotation_sigma is None else _float(rotation_sigma, "rotation_sigma"),
        measurement_frame=_path(measurement_frame, "measurement_frame"),
        length_unit=_optional_text(length_unit, "length_unit"),
        angle_unit=_optional_text(angle_unit, "angle_unit"),
        joint_length_unit=_optional_text(joint_length_unit, "joint_length_unit"),
        tools=None if tools is None else _strings(tools, "tools"),
        ignore_columns=_strings(ignore_columns, "ignore_columns"),
        add_tool_links=_flag(add_tool_links, "add_tool_links"),
    )
    return Calibration(inner)


def _calibrate_contacts(
    robot: Any, contacts: Any, contact_setup: Any, validation: Any, reference_link: Any,
    measurements: Any, position_sigma: Any, rotation_sigma: Any, measurement_frame: Any,
    length_unit: Any, ignore_columns: Any, model_arguments: Dict[str, Any], seed: Any,
    tools: Any = None,
) -> "Calibration":
    """`calibrate` from contacts (see there)."""
    if contacts is None or contact_setup is None:
        raise TreecalError("calibrate: contacts= and contact_setup= go together (the contacts CSV and its setup YAML)")
    for value, name in ((validation, "validation"), (measurements, "measurements")):
        if value is not None and not isinstance(value, (str, os.PathLike)):
            raise TreecalError(f"calibrate: with contacts=, {name}= is a CSV path")
    inner = _native(
        _treecal.calibrate_contacts_files,
        robot=_robot_path(robot),
        contacts=_path(contacts, "contacts"),
        contact_setup=_path(contact_setup, "contact_setup"),
        validation=None if validation is None else _path(validation, "validation"),
        reference_link=_optional_text(reference_link, "reference_link"),
        measurements=None if measurements is None else _path(measurements, "measurements"),
        position_sigma=None if position_sigma is None else _float(position_sigma, "position_sigma"),
        rotation_sigma=None if rotation_sigma is None else _float(rotation_sigma, "rotation_sigma"),
        measurement_frame=_path(measurement_frame, "measurement_frame"),
        length_unit=_optional_text(length_unit, "length_unit"),
        ignore_columns=_strings(ignore_columns, "ignore_columns"),
        seed=_seed(seed),
        tools=None if tools is None else _strings(tools, "tools"),
        **model_arguments,
    )
    return Calibration(inner)


class Verification:
    """The outcome of :func:`verify`: ``report`` (report.json as a dict), ``markdown``
    (report.md) and ``passed`` (the RMS position error within `max_error`, or no tolerance)."""

    def __init__(self, report_json: str, markdown: str, passed: bool) -> None:
        self.report: Dict[str, Any] = json.loads(report_json)
        self.markdown: str = markdown
        self.passed: bool = passed

    def __repr__(self) -> str:
        rms = self.report["summary"]["rms_position_mm"]
        return f"<treecal.Verification {len(self.report['rows'])} rows, RMS {rms:.3f} mm, passed={self.passed}>"


def verify(
    measurements: Optional[MeasurementsLike] = None,
    *,
    calibration: Optional[PathLike] = None,
    robot: Optional[PathLike] = None,
    registration: Optional[PathLike] = None,
    stiffness: Optional[PathLike] = None,
    frame: str = "fit",
    max_error: Optional[float] = None,
    tools: Optional[Sequence[str]] = None,
    length_unit: Optional[str] = None,
    angle_unit: Optional[str] = None,
    joint_length_unit: Optional[str] = None,
    gravity_frame: str = "measurement",
    out_dir: Optional[PathLike] = None,
) -> Verification:
    """Scores a deployed calibration on fresh `measurements` (``treecal verify``).

    `calibration` is a ``treecal calibrate`` output folder (its calibrated.urdf,
    registration.yaml, stiffness.yaml and the calibrated ranges of report.json); `robot`,
    `registration`, `stiffness` override its files. `frame` is "fit" (the measurement frame
    refitted, 6 parameters per session), "registration" (as written: calibrate's validation
    figures) or "base". `max_error` (mm) is the tolerance on the RMS position error; a failed
    verdict does not raise (see :attr:`Verification.passed`). With `out_dir` the files are
    written there like ``--out``.
    """
    if measurements is None:
        raise TreecalError("verify: measurements= is required (a CSV path or treecal.Measurements)")
    report_json, markdown, passed = _native(
        _treecal.verify,
        measurements=_measurement_source(measurements, "measurements"),
        calibration=None if calibration is None else _path(calibration, "calibration"),
        robot=None if robot is None else _path(robot, "robot"),
        registration=None if registration is None else _path(registration, "registration"),
        stiffness=None if stiffness is None else _path(stiffness, "stiffness"),
        frame=_text(frame, "frame"),
        max_error=None if max_error is None else _float(max_error, "max_error"),
        tools=None if tools is None else _strings(tools, "tools"),
        length_unit=_optional_text(length_unit, "length_unit"),
        angle_unit=_optional_text(angle_unit, "angle_unit"),
        joint_length_unit=_optional_text(joint_length_unit, "joint_length_unit"),
        gravity_frame=_text(gravity_frame, "gravity_frame"),
        out_dir=None if out_dir is None else _path(out_dir, "out_dir"),
    )
    return Verification(report_json, markdown, passed)


def compare(
    a: PathLike,
    b: PathLike,
    *,
    k: float = 3.0,
    out_dir: Optional[PathLike] = None,
) -> Dict[str, Any]:
    """Compares two ``treecal calibrate`` output folders (``treecal compare``): returns
    report.json as a dict (``moved``: parameters beyond `k` combined σ; ``displacement``: the
    predicted tool displacement; ``validation``: both folders' figures). With `out_dir` the
    files are written there."""
    report_json, _markdown = _native(
        _treecal.compare,
        a=_path(a, "a"),
        b=_path(b, "b"),
        k=_float(k, "k"),
        out_dir=None if out_dir is None else _path(out_dir, "out_dir"),
    )
    return json.loads(report_json)
