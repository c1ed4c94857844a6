"""Type stubs of the Rust extension module (python/src); use the `treecal` package instead."""

from typing import Any, Dict, List, Optional, Tuple, Union

__version__: str

class TreecalError(ValueError):
    """Bad input or a calibration that cannot run; the message is the CLI's error text."""

class Calibration:
    @property
    def verdict_json(self) -> str: ...
    @property
    def parameters_json(self) -> str: ...
    @property
    def report_json(self) -> str: ...
    @property
    def markdown(self) -> str: ...
    @property
    def urdf(self) -> Optional[str]: ...
    @property
    def notes(self) -> List[Tuple[str, str]]: ...
    def files(self) -> List[Tuple[str, bytes]]: ...
    def write(self, out: str) -> None: ...
    def write_urdf(self, path: str) -> None: ...

def fk(
    robot: Optional[str],
    tip: str,
    joint_names: List[str],
    joints: List[List[float]],
    angle_unit: str = "rad",
    first_row: int = 0,
) -> List[List[float]]: ...

def calibrate(
    *,
    robot: Optional[str],
    measurements: Union[str, Dict[str, Any]],
    validation: Union[None, str, Dict[str, Any]],
    length_unit: Optional[str],
    angle_unit: Optional[str],
    joint_length_unit: Optional[str],
    stiffness: Optional[str],
    tools: Optional[List[str]],
    reference_link: Optional[str],
    plan: Optional[str],
    seed: int,
    robust: str,
    identify_stiffness: bool,
    stiffness_prior: Optional[float],
    measurement_frame: str,
    gravity_frame: str,
    position_sigma: Optional[float],
    rotation_sigma: Optional[float],
    ignore_columns: List[str],
    strict: bool,
    add_tool_links: bool,
    model: str,
    prior: bool,
    prior_scale: float,
    cv: Optional[int],
    freeze: List[str],
    free: List[str],
) -> Calibration: ...

def calibrate_camera(
    *,
    robot: Optional[str],
    camera: str,
    detections: Optional[str],
    detections_csv: Optional[str],
    validation: Optional[str],
    measurements: Optional[str],
    pixel_sigma: float,
    position_sigma: Optional[float],
    rotation_sigma: Optional[float],
    measurement_frame: str,
    length_unit: Optional[str],
    angle_unit: Optional[str],
    joint_length_unit: Optional[str],
    tools: Optional[List[str]],
    ignore_columns: List[str],
    add_tool_links: bool,
) -> Calibration: ...

def calibrate_contacts_files(
    *,
    robot: Optional[str],
    contacts: str,
    contact_setup: str,
    validation: Optional[str],
    reference_link: Optional[str],
    measurements: Optional[str],
    position_sigma: Optional[float],
    rotation_sigma: Optional[float],
    measurement_frame: str,
    length_unit: Optional[str],
    ignore_columns: List[str],
    model: str,
    prior: bool,
    prior_scale: float,
    cv: Optional[int],
    seed: int,
    freeze: List[str],
    free: List[str],
    tools: Optional[List[str]] = None,
) -> Calibration: ...

def verify(
    *,
    measurements: Union[str, Dict[str, Any]],
    calibration: Optional[str],
    robot: Optional[str],
    registration: Optional[str],
    stiffness: Optional[str],
    frame: str,
    max_error: Optional[float],
    tools: Optional[List[str]],
    length_unit: Optional[str],
    angle_unit: Optional[str],
    joint_length_unit: Optional[str],
    gravity_frame: str,
    out_dir: Optional[str],
) -> Tuple[str, str, bool]: ...

def compare(a: str, b: str, *, k: float, out_dir: Optional[str]) -> Tuple[str, str]: ...
