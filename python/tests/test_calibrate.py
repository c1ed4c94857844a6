"""treecal.calibrate: a simulated Robonaut from arrays and from CSV, the outcome, the errors."""

from __future__ import annotations

import csv
import json
import re
import subprocess

import numpy as np
import pytest

import treecal
from conftest import EXAMPLE_CSV, ROBONAUT, STIFFNESS

TOOLS = ("left_tool", "right_tool")


def read_example():
    """robots/robonaut/example/measurements.csv as arrays (mm, deg, three targets)."""
    with EXAMPLE_CSV.open() as f:
        lines = [line for line in f if not line.startswith("#")]
    rows = list(csv.DictReader(lines))
    header = list(rows[0].keys())
    joints = header[header.index("tool") + 1 : header.index("ax")]
    targets = [f"{t}{c}" for t in "abc" for c in "xyz"]
    return treecal.Measurements(
        tools=[r["tool"] for r in rows],
        joints=[[float(r[j]) for j in joints] for r in rows],
        joint_names=joints,
        targets=[[float(r[t]) for t in targets] for r in rows],
        ids=[r["id"] for r in rows],
        stages=[r["stage"] for r in rows],
        length_unit="mm",
        angle_unit="deg",
    )


@pytest.fixture(scope="module")
def from_csv():
    return treecal.calibrate(measurements=EXAMPLE_CSV, stiffness=STIFFNESS)


@pytest.fixture(scope="module")
def from_arrays():
    return treecal.calibrate(measurements=read_example(), stiffness=STIFFNESS)


def test_arrays_and_csv_give_the_same_calibration(from_csv, from_arrays):
    assert from_csv.verdict == "ok", from_csv.reasons
    assert from_arrays.verdict == "ok", from_arrays.reasons
    assert len(from_csv.parameters) > 50
    assert [p["name"] for p in from_csv.parameters] == [p["name"] for p in from_arrays.parameters]
    for a, b in zip(from_csv.parameters, from_arrays.parameters):
        assert a["calibrated"] == pytest.approx(b["calibrated"], abs=1e-12), a["name"]
        assert a["std_dev"] == pytest.approx(b["std_dev"], rel=1e-9, abs=1e-15), a["name"]
        assert a.keys() >= {"name", "owner", "kind", "unit", "nominal", "calibrated", "change", "std_dev", "identifiable"}
    assert from_csv.urdf == from_arrays.urdf


def test_the_calibration_finds_the_simulated_errors(from_csv):
    # The example's parameters are off by up to 0.05 rad / 5 cm: calibration must move them.
    moved = [p for p in from_csv.parameters if p["identifiable"] and abs(p["change"]) > 1e-3]
    assert len(moved) > 10
    assert all(p["calibrated"] == pytest.approx(p["nominal"] + p["change"], abs=1e-12) for p in from_csv.parameters)
    assert from_csv.report["verdict"]["status"] == "ok"
    assert [r["code"] for r in from_csv.reasons] == [r["code"] for r in from_csv.report["verdict"]["reasons"]]
    assert any("held out" in text for level, text in from_csv.notes)
    assert "calibrat" in from_csv.markdown.lower()
    assert from_csv.urdf is not None and "<robot" in from_csv.urdf


def test_write_and_write_urdf(from_csv, tmp_path):
    from_csv.write(tmp_path / "out")
    files = from_csv.files
    assert "report.json" in files and "calibrated.urdf" in files
    for name, data in files.items():
        assert (tmp_path / "out" / name).read_bytes() == data, name
    # .report is report.json's content, .markdown report.md, .urdf calibrated.urdf.
    assert json.loads(files["report.json"]) == from_csv.report
    assert from_csv.report["schema_version"].startswith("treecal.report/")
    assert files["report.md"].decode() == from_csv.markdown
    assert files["calibrated.urdf"].decode() == from_csv.urdf
    from_csv.write_urdf(tmp_path / "cal.urdf")
    assert (tmp_path / "cal.urdf").read_text() == from_csv.urdf
    # The calibrated URDF loads and moves like a robot.
    pose = treecal.fk(tmp_path / "cal.urdf", "left_tool", {"left_joint1": 0.2})
    assert pose.shape == (4, 4)


def quaternion(r: np.ndarray) -> np.ndarray:
    """w, x, y, z of a rotation matrix (w >= 0)."""
    w = np.sqrt(max(0.0, 1.0 + np.trace(r))) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)


def perturbed_robonaut(rng) -> str:
    """The built-in Robonaut with every joint origin moved (±3 mm, ±3 mrad): the 'real' robot."""

    def move_origin(match):
        xyz = np.array([float(v) for v in match.group(1).split()]) + rng.uniform(-3e-3, 3e-3, 3)
        rpy = np.array([float(v) for v in match.group(2).split()]) + rng.uniform(-3e-3, 3e-3, 3)
        text = lambda values: " ".join(repr(float(v)) for v in values)  # noqa: E731
        return f'<origin xyz="{text(xyz)}" rpy="{text(rpy)}"/>'

    def move_joint(match):
        return re.sub(r'<origin xyz="([^"]*)" rpy="([^"]*)"/>', move_origin, match.group(0))

    return re.sub(r"<joint .*?</joint>", move_joint, ROBONAUT.read_text(), flags=re.S)


def simulate(truth, names, count, rng, noise=(2e-5, 2e-4)) -> treecal.Measurements:
    """Poses of both tools of `truth` in random configurations, with seeded noise."""
    joints = rng.uniform(-1.2, 1.2, size=(count, len(names)))
    rows, tools = [], []
    for tool in TOOLS:
        poses = treecal.fk(truth, tool, joints, joint_names=names)
        for pose in poses:
            xyz = pose[:3, 3] + rng.normal(0, noise[0], 3)
            small = rng.normal(0, noise[1], 3)
            tilt = np.array([[1, -small[2], small[1]], [small[2], 1, -small[0]], [-small[1], small[0], 1]])
            u, _, vt = np.linalg.svd(tilt @ pose[:3, :3])
            rows.append([*xyz, *quaternion(u @ vt)])
            tools.append(tool)
    return treecal.Measurements(
        tools=tools,
        joints=np.vstack([joints, joints]),
        joint_names=names,
        poses=np.array(rows),
        ids=[f"{tool}-{i}" for tool in TOOLS for i in range(count)],
    )


def test_a_robot_simulated_in_python_is_calibrated_from_arrays(tmp_path):
    rng = np.random.default_rng(7)
    truth = tmp_path / "truth.urdf"
    truth.write_text(perturbed_robonaut(rng))
    names = re.findall(r'<joint name="([a-z_0-9]+)" type="revolute"', ROBONAUT.read_text())
    measured = simulate(truth, names, 30, rng)
    cal = treecal.calibrate(None, measured, measurement_frame="base", position_sigma=2e-5, rotation_sigma=2e-4)
    assert cal.verdict in ("ok", "warning"), cal.reasons
    assert cal.verdict == "ok", [r for r in cal.reasons if r["status"] != "ok"]
    cal.write_urdf(tmp_path / "cal.urdf")
    # On new configurations, the calibrated model predicts the real robot's tools to well
    # under a millimetre where the nominal model is off by centimetres.
    check = rng.uniform(-1.2, 1.2, size=(20, len(names)))
    for tool in TOOLS:
        real = treecal.fk(truth, tool, check, joint_names=names)[:, :3, 3]
        nominal = treecal.fk(None, tool, check, joint_names=names)[:, :3, 3]
        calibrated = treecal.fk(tmp_path / "cal.urdf", tool, check, joint_names=names)[:, :3, 3]
        before = np.linalg.norm(real - nominal, axis=1).mean()
        after = np.linalg.norm(real - calibrated, axis=1).mean()
        assert before > 5e-3, (tool, before)
        assert after < 1e-4, (tool, after)


def test_a_failed_verdict_is_an_outcome_and_write_urdf_refuses(tmp_path):
    # Validation measured on another robot (the nominal one): the calibrated model cannot
    # predict it, so the verdict fails; calibrate returns it and exports no URDF.
    rng = np.random.default_rng(8)
    truth = tmp_path / "truth.urdf"
    truth.write_text(perturbed_robonaut(rng))
    names = re.findall(r'<joint name="([a-z_0-9]+)" type="revolute"', ROBONAUT.read_text())
    measured = simulate(truth, names, 30, rng)
    other = simulate(ROBONAUT, names, 10, rng)
    cal = treecal.calibrate(None, measured, other, measurement_frame="base", position_sigma=2e-5, rotation_sigma=2e-4)
    assert cal.verdict == "failed" and not cal.usable
    assert "validation-worse" in [r["code"] for r in cal.reasons if r["status"] == "failed"]
    assert cal.urdf is None and "calibrated.urdf" not in cal.files
    with pytest.raises(treecal.TreecalError, match="verdict is failed.*validation"):
        cal.write_urdf(tmp_path / "cal.urdf")
    assert not (tmp_path / "cal.urdf").exists()
    cal.write(tmp_path / "out")  # the reports are written, as the CLI does before exiting 1
    assert (tmp_path / "out" / "report.md").is_file()


def test_bad_values_name_the_row(tmp_path):
    measured = read_example()
    measured.observations[4, 2] = np.nan
    with pytest.raises(treecal.TreecalError, match=r"measurements \(arrays\).*\b5\b"):
        treecal.calibrate(measurements=measured)
    measured = read_example()
    measured.tools[1] = "left_tol"
    with pytest.raises(treecal.TreecalError, match="left_tol"):
        treecal.calibrate(measurements=measured)


def test_bad_csv_names_the_file_and_line(tmp_path):
    lines = EXAMPLE_CSV.read_text().splitlines()
    fields = lines[3].split(",")
    fields[5] = "twelve"
    lines[3] = ",".join(fields)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(treecal.TreecalError, match=r"bad\.csv:4.*twelve"):
        treecal.calibrate(measurements=bad)


def test_the_error_message_is_the_cli_s(cli, tmp_path):
    lines = EXAMPLE_CSV.read_text().splitlines()
    lines[6] = lines[6].replace("left_tool", "left_tol", 1)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    result = subprocess.run(
        [cli, "calibrate", "--measurements", str(bad), "--out", str(tmp_path / "out")],
        capture_output=True, text=True,
    )
    assert result.returncode != 0
    cli_error = [line for line in result.stderr.splitlines() if line.startswith("treecal: error: ")]
    assert len(cli_error) == 1, result.stderr
    with pytest.raises(treecal.TreecalError) as raised:
        treecal.calibrate(measurements=bad)
    # The same text, with the CLI's flags named as the keyword arguments Python users pass.
    special = {"out": "out_dir", "plan-file": "plan"}
    as_keywords = re.sub(
        r"--([a-z][a-z-]*)",
        lambda m: special.get(m.group(1), m.group(1).replace("-", "_")),
        cli_error[0][len("treecal: error: "):],
    )
    assert str(raised.value) == as_keywords
    assert "--" not in str(raised.value)
    assert "left_tol" in str(raised.value)


def test_bad_arguments_raise_treecal_errors():
    with pytest.raises(treecal.TreecalError, match="robust 'hubber'"):
        treecal.calibrate(measurements=EXAMPLE_CSV, robust="hubber")
    with pytest.raises(treecal.TreecalError, match="exactly one of"):
        treecal.Measurements(["left_tool"], [[0.0]], ["left_joint1"])
    with pytest.raises(treecal.TreecalError, match=r"expected 3 columns"):
        treecal.Measurements(["left_tool"], [[0.0]], ["left_joint1"], positions=[[0.0, 1.0]])
    with pytest.raises(treecal.TreecalError, match="nowhere.csv"):
        treecal.calibrate(measurements="nowhere.csv")


def test_a_bad_setting_names_the_keyword():
    # The library names the setting; Python shows the keyword argument, never the CLI's flag.
    with pytest.raises(treecal.TreecalError) as raised:
        treecal.calibrate(measurements=EXAMPLE_CSV, length_unit="cm")
    assert str(raised.value).startswith("length_unit: 'cm' is not a length unit"), raised.value
    with pytest.raises(treecal.TreecalError) as raised:
        treecal.calibrate(measurements=EXAMPLE_CSV, position_sigma=-1.0)
    message = str(raised.value)
    assert message.startswith("position_sigma: ") and "--" not in message and "`" not in message


def test_measurements_carry_sessions_and_points():
    table = treecal.Measurements(
        tools=["left_link6", "left_link6"],
        joints=[[0.0], [0.1]],
        joint_names=["left_joint1"],
        positions=[[0.0, 0.0, 0.0], [0.0, 0.0, 0.1]],
        sessions=["day1", "day2"],
        points=["P1", "P2"],
    )
    payload = table._payload()
    assert payload["sessions"] == ["day1", "day2"]
    assert payload["points"] == ["P1", "P2"]
    with pytest.raises(treecal.TreecalError, match="sessions"):
        treecal.Measurements(
            tools=["left_link6"],
            joints=[[0.0]],
            joint_names=["left_joint1"],
            positions=[[0.0, 0.0, 0.0]],
            sessions=["day1", "day2"],
        )


def test_reference_link_is_a_keyword():
    # An unknown reference link is an error that lists the robot's links.
    with pytest.raises(treecal.TreecalError, match=r"reference link 'base_lnk'.*base_link"):
        treecal.calibrate(measurements=EXAMPLE_CSV, reference_link="base_lnk")
    # The root named explicitly is the default: the same calibration.
    root = treecal.calibrate(measurements=EXAMPLE_CSV, reference_link="base_link")
    default = treecal.calibrate(measurements=EXAMPLE_CSV)
    assert root.parameters == default.parameters


def test_the_model_keywords_reach_the_calibration():
    offsets = treecal.calibrate(measurements=EXAMPLE_CSV, model="offsets", seed=3)
    names = {p["name"] for p in offsets.parameters}
    assert any(n.endswith(" offset") for n in names), sorted(names)[:10]
    assert offsets.report["model"]["spec"]["level"] == "offsets", offsets.report["model"]
    frozen = treecal.calibrate(measurements=EXAMPLE_CSV, model="geometry", freeze=["left_joint1 *"], seed=3)
    moved = {p["name"]: p["change"] for p in frozen.parameters}
    assert all(v == 0.0 for n, v in moved.items() if n.startswith("left_joint1 ")), moved
    with pytest.raises(treecal.TreecalError, match="prior_scale"):
        treecal.calibrate(measurements=EXAMPLE_CSV, prior=True, prior_scale=0)


def test_a_list_of_files_is_one_set_with_a_session_per_file(tmp_path):
    # The example split in two files (header and comment lines kept): each is its own session.
    lines = EXAMPLE_CSV.read_text().splitlines(keepends=True)
    head = [line for line in lines if line.startswith("#")]
    rows = [line for line in lines if not line.startswith("#")]
    header, data = rows[0], rows[1:]
    # Configuration by configuration (each measures both tools on two rows), alternately.
    parts = ([r for i, r in enumerate(data) if i // 2 % 2 == k] for k in (0, 1))
    first, second = tmp_path / "monday.csv", tmp_path / "tuesday.csv"
    for path, part in zip((first, second), parts):
        path.write_text("".join(head + [header] + part))
    result = treecal.calibrate(measurements=[first, second], seed=3)
    names = [s["name"] for s in result.report["sessions"]["training"]]
    assert names == ["monday", "tuesday"], result.report["sessions"]
    assert any("2 measurement files read as one set" in text for _, text in result.notes)
    with pytest.raises(treecal.TreecalError, match="measurements"):
        treecal.calibrate(measurements=[], seed=3)
