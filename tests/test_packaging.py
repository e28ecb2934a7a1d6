"""The wheel carries everything a run needs outside the repository."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_holds_models_and_scenarios(tmp_path: Path) -> None:
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(tmp_path),
         str(ROOT)],
        check=True, capture_output=True, timeout=600,
    )
    (wheel,) = tmp_path.glob("cosim_testbed-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert "cosim/models/sedan.xml" in names
    assert "cosim/models/README.md" in names
    assert "cosim/scenarios/lane-change.yaml" in names
    assert "cosim/scenarios/lane-change-limit.yaml" in names
    assert {"tracker/mpc/kinematic_nmpc.py", "estimation/ekf.py", "cosim/cli.py"} <= names
    entry_points = next(n for n in names if n.endswith("entry_points.txt"))
    assert "cosim = cosim.cli:main" in zipfile.ZipFile(wheel).read(entry_points).decode()
