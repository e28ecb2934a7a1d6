"""The example FMUs drive the whole lane change through `cosim run`, `compare` and `sweep`.

The property is the run's outcome: ``ok`` means the car stayed within half a lane of the
path (``outcome.lane_width_m``), did not spin and reached the end; a tracker with a sign
error or a broken signal mapping leaves the lane within seconds.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.log.reader import read_summary

COSIM = str(Path(sys.executable).with_name("cosim"))


def cosim(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([COSIM, *args], capture_output=True, text=True, cwd=cwd,
                          timeout=900, check=False)


@pytest.mark.slow
@pytest.mark.parametrize(("kind", "version"), [("c", 2), ("c", 3), ("python", 2),
                                               ("python", 3)])
def test_cosim_run_completes_the_lane_change(kind: str, version: int,
                                             c_fmus: dict[int, Path],
                                             python_fmus: dict[int, Path],
                                             tmp_path: Path) -> None:
    fmu = (c_fmus if kind == "c" else python_fmus)[version]
    done = cosim("run", "lane-change", "--tracker", f"fmu:{fmu}", "--out", "run.mcap",
                 "--json", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    metrics = json.loads(done.stdout)["metrics"]
    assert metrics["outcome"] == "ok" and metrics["completed"] is True, metrics
    summary = read_summary(tmp_path / "run.mcap")
    config = json.loads(summary.metadata["run"]["config_json"])
    assert config["tracker"]["name"] == f"fmu:{fmu}"
    assert summary.duration_s == pytest.approx(15.0, abs=0.02)


@pytest.mark.slow
def test_cosim_compare_and_sweep_run_fmus(c_fmus: dict[int, Path],
                                          python_fmus: dict[int, Path],
                                          tmp_path: Path) -> None:
    """compare: the C FMU (FMI 2) against the Python one (FMI 3); sweep: the other two."""
    compared_names = [f"fmu:{c_fmus[2]}", f"fmu:{python_fmus[3]}"]
    compared = cosim("compare", "--trackers", ",".join(compared_names), "--scenarios",
                     "lane-change", "--workers", "2", "--json", "--out", "league",
                     cwd=tmp_path)
    assert compared.returncode == 0, compared.stderr
    rows = json.loads(compared.stdout)
    assert sorted(r["tracker"] for r in rows) == sorted(compared_names)
    assert all(r["metrics"]["outcome"] == "ok" for r in rows), rows
    swept_names = [f"fmu:{c_fmus[3]}", f"fmu:{python_fmus[2]}"]
    (tmp_path / "spec.yaml").write_text(
        "scenario: lane-change\nseeds: 1\ngrid:\n  tracker.name: ["
        + ", ".join(json.dumps(n) for n in swept_names) + "]\npass:\n  completed: true\n")
    swept = cosim("sweep", "spec.yaml", "--workers", "2", "--out", "sweep", cwd=tmp_path)
    assert swept.returncode == 0, swept.stderr
    results = [json.loads(line) for line in
               (tmp_path / "sweep" / "results.jsonl").read_text().splitlines()]
    assert sorted(r["params"]["tracker.name"] for r in results) == sorted(swept_names)
    assert all(r["metrics"]["outcome"] == "ok" for r in results), results
