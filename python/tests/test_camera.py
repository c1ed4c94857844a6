"""treecal.calibrate with a camera: the camera file and the detections (a CSV path, or rows in
memory) from `treecal simulate --observation camera`, as `treecal calibrate --camera` reads them."""

from __future__ import annotations

import csv
import subprocess
from pathlib import Path

import pytest

import treecal


@pytest.fixture(scope="module")
def simulated(cli: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("camera") / "sim"
    subprocess.run(
        [cli, "simulate", "--observation", "camera", "--trials", "1", "--poses", "12", "-o", str(out)],
        check=True,
        capture_output=True,
    )
    return out


def test_calibrate_with_a_camera_file_and_detections(simulated: Path) -> None:
    result = treecal.calibrate(
        camera=simulated / "cameras.yaml",
        detections=simulated / "detections.csv",
        validation=simulated / "validation_detections.csv",
    )
    assert result.usable, result.reasons
    assert result.urdf is not None and "<robot" in result.urdf
    kinds = result.report["kinds"]
    assert [k["kind"] for k in kinds] == ["pixel"]
    assert 0.7 < kinds[0]["residual_scale"] < 1.4
    held = result.report["held_out"]
    assert held["after"]["rms_px"] < 0.2 * held["before"]["rms_px"]
    assert any(p["determined"] for p in result.parameters)
    assert "cameras_calibrated.yaml" in result.files


def test_detections_in_memory_give_the_same_fit(simulated: Path) -> None:
    text = (simulated / "detections.csv").read_text()
    assert "angle=deg" not in text
    rows = list(csv.DictReader(line for line in text.splitlines() if not line.startswith("#")))
    from_rows = treecal.calibrate(camera=simulated / "cameras.yaml", detections=rows)
    from_file = treecal.calibrate(camera=simulated / "cameras.yaml", detections=simulated / "detections.csv")
    assert from_rows.report["fit"]["residual_scale"] == pytest.approx(
        from_file.report["fit"]["residual_scale"], rel=1e-9
    )


def test_camera_input_errors_are_named(simulated: Path) -> None:
    with pytest.raises(treecal.TreecalError, match="detections"):
        treecal.calibrate(camera=simulated / "cameras.yaml")
    bad = [{"id": "a", "camera": "nope", "target": "x", "corner": 0, "u": 1.0, "v": 2.0}]
    with pytest.raises(treecal.TreecalError):
        treecal.calibrate(camera=simulated / "cameras.yaml", detections=bad)
