"""treecal.fk against the CLI's `treecal fk`, and its argument checks."""

from __future__ import annotations

import csv
import subprocess

import numpy as np
import pytest

import treecal
from conftest import ROBONAUT


def cli_fk(cli: str, robot, tip: str, names, rows, tmp_path, angle_unit="rad") -> np.ndarray:
    """`treecal fk` on a joints CSV made of `rows`: (N, 4, 4) from its x,y,z,r11..r33 columns."""
    joints = tmp_path / "joints.csv"
    with joints.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(names)
        writer.writerows([[repr(float(v)) for v in row] for row in rows])
    result = subprocess.run(
        [cli, "fk", "--robot", str(robot), "--tip", tip, "--joints", str(joints), "--angle-unit", angle_unit],
        check=True, capture_output=True, text=True,
    )
    table = list(csv.DictReader(result.stdout.splitlines()))
    poses = np.zeros((len(table), 4, 4))
    for pose, row in zip(poses, table):
        pose[:3, 3] = [float(row[k]) for k in ("x", "y", "z")]
        pose[:3, :3] = np.array([float(row[f"r{i}{j}"]) for i in (1, 2, 3) for j in (1, 2, 3)]).reshape(3, 3)
        pose[3, 3] = 1.0
    return poses


def random_joints(names, count, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.5, 1.5, size=(count, len(names)))


def test_fk_equals_the_cli_on_talos(cli, talos, tmp_path):
    names = ["torso_1_joint", "torso_2_joint", "arm_left_1_joint", "arm_left_2_joint",
             "arm_left_3_joint", "arm_left_4_joint", "arm_left_5_joint", "arm_left_6_joint",
             "arm_left_7_joint"]
    joints = random_joints(names, 25, seed=1)
    ours = treecal.fk(talos, "arm_left_7_link", joints, joint_names=names)
    theirs = cli_fk(cli, talos, "arm_left_7_link", names, joints, tmp_path)
    assert ours.shape == (25, 4, 4)
    assert np.max(np.abs(ours - theirs)) <= 1e-12
    # A real pose: orthonormal rotation, bottom row 0 0 0 1, the arm moves the link.
    assert np.allclose(ours[:, 3], [0, 0, 0, 1])
    assert np.allclose(ours[:, :3, :3] @ ours[:, :3, :3].transpose(0, 2, 1), np.eye(3), atol=1e-12)
    assert np.ptp(ours[:, 0, 3]) > 0.1


def test_fk_equals_the_cli_on_robonaut_in_degrees(cli, tmp_path):
    names = ["torso_joint1", "torso_joint2", "right_joint1", "right_joint2", "right_joint3"]
    joints = np.degrees(random_joints(names, 10, seed=2))
    ours = treecal.fk(ROBONAUT, "right_tool", joints, joint_names=names, angle_unit="deg")
    theirs = cli_fk(cli, ROBONAUT, "right_tool", names, joints, tmp_path, angle_unit="deg")
    assert np.max(np.abs(ours - theirs)) <= 1e-12


def test_fk_of_a_dict_is_one_pose_and_missing_joints_are_zero():
    single = treecal.fk(None, "left_tool", {"left_joint2": 0.3})
    names = ["left_joint1", "left_joint2", "torso_joint1"]
    rows = treecal.fk(None, "left_tool", [[0.0, 0.3, 0.0]], joint_names=names)
    assert single.shape == (4, 4)
    assert np.array_equal(single, rows[0])
    assert not np.allclose(single, treecal.fk(None, "left_tool", {}))


def test_fk_errors_name_the_link_or_joint():
    with pytest.raises(treecal.TreecalError, match="unknown link 'left_tol'.*left_tool"):
        treecal.fk(None, "left_tol", {"left_joint1": 0.0})
    with pytest.raises(treecal.TreecalError, match="unknown joint 'left_joint99'"):
        treecal.fk(None, "left_tool", {"left_joint99": 0.0})
    with pytest.raises(treecal.TreecalError, match="joint_names"):
        treecal.fk(None, "left_tool", np.zeros((3, 2)))
    with pytest.raises(treecal.TreecalError, match="3 columns but joint_names names 2"):
        treecal.fk(None, "left_tool", np.zeros((3, 3)), joint_names=["left_joint1", "left_joint2"])
    with pytest.raises(treecal.TreecalError, match="'grad' is not an angle unit"):
        treecal.fk(None, "left_tool", {"left_joint1": 0.0}, angle_unit="grad")
    with pytest.raises(treecal.TreecalError, match="joint 'left_joint1': NaN is not a finite number"):
        treecal.fk(None, "left_tool", {"left_joint1": float("nan")})
    with pytest.raises(treecal.TreecalError, match="row 2, joint 'left_joint1': 1e9 is beyond the limit"):
        treecal.fk(None, "left_tool", [[0.0], [1e9]], joint_names=["left_joint1"])
    # TreecalError is a ValueError, so generic handlers catch it.
    assert issubclass(treecal.TreecalError, ValueError)


def test_fk_of_a_missing_urdf_names_the_file(tmp_path):
    missing = tmp_path / "nowhere.urdf"
    with pytest.raises(treecal.TreecalError, match="nowhere.urdf"):
        treecal.fk(missing, "left_tool", {})
