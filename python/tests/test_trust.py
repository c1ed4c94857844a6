"""treecal.verify and treecal.compare: a calibration verified on rows, two folders compared."""

from __future__ import annotations

import treecal
from conftest import EXAMPLE_CSV, ROBONAUT, STIFFNESS


def test_verify_a_calibration_folder_and_compare_it_with_itself(tmp_path):
    calibration = treecal.calibrate(robot=ROBONAUT, measurements=EXAMPLE_CSV, stiffness=STIFFNESS)
    folder = tmp_path / "cal"
    calibration.write(folder)
    assert (folder / "provenance.yaml").is_file()
    loose = treecal.verify(
        EXAMPLE_CSV, calibration=folder, stiffness=STIFFNESS, max_error=1000.0, out_dir=tmp_path / "v"
    )
    assert loose.passed
    assert loose.report["context"]["refitted_parameters"] == 6
    assert len(loose.report["rows"]) > 0
    assert (tmp_path / "v" / "errors.svg").is_file()
    strict = treecal.verify(EXAMPLE_CSV, calibration=folder, stiffness=STIFFNESS, max_error=1e-9)
    assert not strict.passed
    assert strict.report["summary"] == loose.report["summary"]
    report = treecal.compare(folder, folder)
    assert report["moved"] == []


def test_verify_without_a_registration_names_the_keyword_arguments():
    try:
        treecal.verify(EXAMPLE_CSV, frame="registration", robot=ROBONAUT)
    except treecal.TreecalError as error:
        message = str(error)
        assert "frame base" in message and "--frame" not in message, message
    else:
        raise AssertionError("verify without a registration must fail")
