"""treecal.calibrate from contacts: the contacts CSV and its setup YAML from `treecal simulate
--observation flush`, as `treecal calibrate --contacts … --contact-setup …` reads them."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

import treecal


@pytest.fixture(scope="module")
def simulated(cli: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("contacts") / "sim"
    subprocess.run(
        [cli, "simulate", "--observation", "flush", "--trials", "1", "--poses", "20", "-o", str(out)],
        check=True,
        capture_output=True,
    )
    return out


def test_calibrate_from_contacts_matches_the_cli(simulated: Path, cli: str, tmp_path: Path) -> None:
    result = treecal.calibrate(
        contacts=simulated / "contacts.csv",
        contact_setup=simulated / "contact-setup.yaml",
        validation=simulated / "contacts-validation.csv",
    )
    assert result.usable, result.reasons
    assert result.urdf is not None and "<robot" in result.urdf
    assert any(p["name"] for p in result.parameters)
    assert set(result.files) >= {"report.md", "report.json", "calibrated.urdf"}
    out = tmp_path / "cli"
    subprocess.run(
        [cli, "calibrate", "--contacts", str(simulated / "contacts.csv"),
         "--contact-setup", str(simulated / "contact-setup.yaml"),
         "--validation", str(simulated / "contacts-validation.csv"), "-o", str(out)],
        check=True,
        capture_output=True,
    )
    assert json.loads((out / "report.json").read_text()) == result.report
    written = tmp_path / "py"
    result.write(written)
    assert (written / "calibrated.urdf").read_text() == result.urdf


def test_contact_input_errors_are_named(simulated: Path) -> None:
    with pytest.raises(treecal.TreecalError, match="contact_setup"):
        treecal.calibrate(contacts=simulated / "contacts.csv")
    with pytest.raises(treecal.TreecalError, match="nope.csv"):
        treecal.calibrate(contacts=simulated / "nope.csv", contact_setup=simulated / "contact-setup.yaml")


def test_settings_a_contact_calibration_does_not_use_are_refused(simulated: Path) -> None:
    files = {"contacts": simulated / "contacts.csv", "contact_setup": simulated / "contact-setup.yaml"}
    with pytest.raises(treecal.TreecalError, match="identify_stiffness not used with contacts="):
        treecal.calibrate(identify_stiffness=True, **files)
    with pytest.raises(treecal.TreecalError, match="stiffness, plan not used"):
        treecal.calibrate(stiffness="s.yaml", plan="staged", **files)


def test_the_model_flags_match_the_cli(simulated: Path, cli: str, tmp_path: Path) -> None:
    files = {
        "contacts": simulated / "contacts.csv",
        "contact_setup": simulated / "contact-setup.yaml",
        "validation": simulated / "contacts-validation.csv",
    }
    result = treecal.calibrate(model="auto", cv=3, **files)
    assert result.report["model"]["name"] == "geometry", result.report["model_choice"]
    assert [r["model"] for r in result.report["model_choice"]["rows"]] == ["offsets", "geometry", "geometry+prior"]
    out = tmp_path / "cli"
    subprocess.run(
        [cli, "calibrate", "--contacts", str(files["contacts"]), "--contact-setup", str(files["contact_setup"]),
         "--validation", str(files["validation"]), "--model", "auto", "--cv", "3", "-o", str(out)],
        check=True,
        capture_output=True,
    )
    assert json.loads((out / "report.json").read_text()) == result.report
    offsets = treecal.calibrate(model="offsets", freeze=["left_joint1*"], **files)
    assert offsets.report["model"] == {"name": "offsets", "offsets": True, "prior": False}
    with pytest.raises(treecal.TreecalError, match="model 'everything'"):
        treecal.calibrate(model="everything", **files)
    with pytest.raises(treecal.TreecalError, match="cv must be"):
        treecal.calibrate(cv=1, **files)


def test_tools_keep_one_side_of_a_contact_calibration(simulated: Path) -> None:
    """`tools=` keeps the named setup tools, as `--tools` does (it was refused before)."""
    result = treecal.calibrate(
        contacts=simulated / "contacts.csv",
        contact_setup=simulated / "contact-setup.yaml",
        validation=simulated / "contacts-validation.csv",
        tools=["left_tool"],
    )
    assert "left_tool" in result.report["held_out"]["tools"]
    with pytest.raises(treecal.TreecalError, match="no_such_tool"):
        treecal.calibrate(
            contacts=simulated / "contacts.csv",
            contact_setup=simulated / "contact-setup.yaml",
            tools=["no_such_tool"],
        )
