"""Shared fixtures: the repository, the CLI binary, example-robot-data."""

from __future__ import annotations

import os
import shutil
import sysconfig
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
ROBONAUT = REPO / "robots" / "robonaut" / "robonaut.urdf"
EXAMPLE_CSV = REPO / "robots" / "robonaut" / "example" / "measurements.csv"
STIFFNESS = REPO / "robots" / "robonaut" / "stiffness.yaml"


def _missing(what: str) -> None:
    """Fails with TREECAL_REQUIRE_TOOLS=1 (CI), else skips."""
    if os.environ.get("TREECAL_REQUIRE_TOOLS") == "1":
        pytest.fail(f"TREECAL_REQUIRE_TOOLS=1 but {what}")
    pytest.skip(what)


@pytest.fixture(scope="session")
def cli() -> str:
    """The `treecal` CLI: $TREECAL_BIN, else target/{debug,release}/treecal, else on PATH."""
    candidates = [os.environ.get("TREECAL_BIN")]
    candidates += [str(REPO / "target" / p / "treecal") for p in ("debug", "release")]
    candidates.append(shutil.which("treecal"))
    for candidate in candidates:
        if candidate and os.access(candidate, os.X_OK):
            return candidate
    _missing("the treecal CLI is not built (cargo build --locked, or set TREECAL_BIN)")
    raise AssertionError("unreachable")


@pytest.fixture(scope="session")
def talos() -> Path:
    """TALOS (reduced) from the PyPI package example-robot-data."""
    root = os.environ.get("TREECAL_EXAMPLE_ROBOT_DATA")
    robots = Path(root) if root else Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"
    path = robots / "talos_data" / "robots" / "talos_reduced.urdf"
    if not path.is_file():
        _missing("the PyPI package example-robot-data is not installed (tests/oracle/requirements.txt)")
    return path
