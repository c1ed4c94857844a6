"""Issue 21: inputs kept where outputs go are never replaced or deleted, every bad argument
raises TreecalError, and messages name Python keywords rather than CLI flags."""

from __future__ import annotations

import shutil

import pytest

import treecal
from conftest import EXAMPLE_CSV, ROBONAUT, STIFFNESS


@pytest.fixture(scope="module")
def kept_inputs(tmp_path_factory):
    """A calibration whose robot is a file the user then writes to, and whose stiffness file
    sits (under an output's name) in the folder the user then writes to."""
    folder = tmp_path_factory.mktemp("work")
    robot = folder / "robot.urdf"
    (folder / "out").mkdir()
    stiffness = folder / "out" / "stiffness.yaml"
    shutil.copy(ROBONAUT, robot)
    shutil.copy(STIFFNESS, stiffness)
    cal = treecal.calibrate(robot, EXAMPLE_CSV, stiffness=stiffness)
    assert cal.usable, cal.reasons
    return cal, folder, robot, stiffness


def test_write_refuses_a_folder_holding_an_input(kept_inputs):
    cal, folder, robot, stiffness = kept_inputs
    before = stiffness.read_bytes()
    with pytest.raises(treecal.TreecalError, match="holds the input file.*stiffness.yaml"):
        cal.write(folder / "out")
    assert stiffness.read_bytes() == before
    with pytest.raises(treecal.TreecalError, match="holds the input file.*robot.urdf"):
        cal.write(folder)
    # Elsewhere it writes (no false alarm).
    cal.write(folder / "elsewhere")
    assert (folder / "elsewhere" / "report.md").read_text() == cal.markdown


def test_write_urdf_refuses_the_input_robot(kept_inputs):
    cal, folder, robot, stiffness = kept_inputs
    before = robot.read_bytes()
    with pytest.raises(treecal.TreecalError, match="the output is the input file"):
        cal.write_urdf(robot)
    assert robot.read_bytes() == before
    # Elsewhere it writes (no false alarm).
    cal.write_urdf(folder / "calibrated.urdf")
    assert (folder / "calibrated.urdf").read_text() == cal.urdf


@pytest.mark.parametrize(
    "arguments, keyword",
    [
        ({"seed": -1}, "seed"),
        ({"seed": 2**70}, "seed"),
        ({"seed": "7"}, "seed"),
        ({"seed": 1.5}, "seed"),
        ({"position_sigma": "small"}, "position_sigma"),
        ({"rotation_sigma": [1]}, "rotation_sigma"),
        ({"stiffness_prior": object()}, "stiffness_prior"),
        ({"robot": 5}, "robot"),
        ({"stiffness": 3.0}, "stiffness"),
        ({"plan": 1}, "plan"),
        ({"measurement_frame": None}, "measurement_frame"),
        ({"tools": 5}, "tools"),
        ({"ignore_columns": 3}, "ignore_columns"),
        ({"robust": 1}, "robust"),
        ({"gravity_frame": None}, "gravity_frame"),
        ({"length_unit": 1000}, "length_unit"),
        ({"strict": "no"}, "strict"),
        ({"identify_stiffness": 2}, "identify_stiffness"),
        ({"measurements": 12}, "measurements"),
    ],
)
def test_bad_calibrate_arguments_raise_treecal_errors(arguments, keyword):
    given = {"measurements": EXAMPLE_CSV, **arguments}
    with pytest.raises(treecal.TreecalError, match=keyword):
        treecal.calibrate(**given)


@pytest.mark.parametrize(
    "arguments, needle",
    [
        ({"robot": 5}, "robot"),
        ({"tip": 3}, "tip"),
        ({"angle_unit": 1}, "angle_unit"),
        ({"joints": {"left_joint1": "x"}}, "left_joint1"),
        ({"joints": [["a"]], "joint_names": ["left_joint1"]}, "joints"),
        ({"joints": [[0.0]], "joint_names": 7}, "joint_names"),
        ({"joints": [[1e308 * 10]], "joint_names": ["left_joint1"]}, "left_joint1"),
    ],
)
def test_bad_fk_arguments_raise_treecal_errors(arguments, needle):
    given = {"robot": None, "tip": "left_tool", "joints": {}, **arguments}
    with pytest.raises(treecal.TreecalError, match=needle):
        treecal.fk(**given)


def test_a_joint_named_twice_is_an_error():
    with pytest.raises(treecal.TreecalError, match="'left_joint1' is named twice"):
        treecal.fk(None, "left_tool", [[0.1, 0.2]], joint_names=["left_joint1", "left_joint1"])
    with pytest.raises(treecal.TreecalError, match="'left_joint1' is named twice"):
        treecal.Measurements(
            ["left_tool"], [[0.0, 0.0]], ["left_joint1", "left_joint1"], positions=[[0.0, 0.0, 1.0]]
        )


def test_messages_name_python_keywords_not_cli_flags():
    with pytest.raises(treecal.TreecalError) as raised:
        treecal.calibrate(measurements=EXAMPLE_CSV, position_sigma=1e-30)
    message = str(raised.value)
    assert "position_sigma" in message and "--position-sigma" not in message, message
    with pytest.raises(treecal.TreecalError) as raised:
        treecal.calibrate(measurements=EXAMPLE_CSV, identify_stiffness=True, stiffness_prior=-1.0)
    message = str(raised.value)
    assert "stiffness_prior" in message and "--" not in message, message
