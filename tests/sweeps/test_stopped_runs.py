"""A run that stopped early (a spin ...) is never a pass, and its metrics are never shown as
whole ones: in the rows, the summary, the heat map, the league table and ``--fail-if``.

The case is a user's: the lane change with ``kinematic-nmpc``, seed 5, a 1,300 kg car on
friction 0.35 against a controller that believes 1,575 kg and friction 1. The car spins
about three seconds in and the run stops there; its ``cte_max_m`` over those seconds is
under the bound and close to the nominal car's over the whole run.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.sweeps.compare import league, markdown
from cosim.sweeps.plots import heat_map
from cosim.sweeps.results import SweepDir, bad_outcome, grid_cells, summary_markdown, write_tables
from cosim.sweeps.spec import load_spec

COSIM = str(Path(sys.executable).with_name("cosim"))

SPUN_SPEC = """
scenario: lane-change
tracker: kinematic-nmpc
seeds: [5]
grid:
  plant.mass_kg: [1300]
  plant.tyre_friction: [1.0, 0.35]
pass: {cte_max_m: 0.3}
"""


@pytest.fixture(scope="module")
def spun_sweep(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sweep of the module docstring, run as a user runs it."""
    root = tmp_path_factory.mktemp("spun")
    (root / "spec.yaml").write_text(SPUN_SPEC)
    done = subprocess.run([COSIM, "sweep", str(root / "spec.yaml"), "--out",
                           str(root / "out"), "--workers", "1", "--exit-zero"],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return root / "out"


def test_the_spun_run_fails_everywhere_it_appears(spun_sweep: Path) -> None:
    document = json.loads((spun_sweep / "results.json").read_text())
    nominal, low_grip = document["rows"]
    assert nominal["outcome"] == "ok" and nominal["pass"] and not nominal["partial"]
    assert low_grip["outcome"] == "spun" and low_grip["partial"]
    # The trap: the partial metric is under the bound, so a criterion alone would pass it.
    assert low_grip["cte_max_m"] < 0.3
    raw = next(json.loads(line) for line in (spun_sweep / "results.jsonl").open()
               if json.loads(line)["run_id"] == 1)
    spun_at = f"spun at {raw['metrics']['spun_t_s']:.2f} s"
    assert low_grip["stopped"] == spun_at
    assert not low_grip["pass"] and low_grip["failed"].startswith(f"outcome {spun_at}")
    assert document["passed"] == 1
    summary = (spun_sweep / "summary.md").read_text()
    assert "**1 of 2 runs pass (50.0 %)**" in summary
    worst = summary.split("## Worst cases")[1].split("##")[0]
    assert f"*partial* | {spun_at} | **FAIL**" in worst
    grid = summary.split("per grid point")[1].split("##")[0]
    assert f"| 0.35 | {spun_at} FAIL |" in grid
    assert f"{low_grip['cte_max_m']:.4g}" not in grid
    csv_header = (spun_sweep / "results.csv").read_text().splitlines()[0].split(",")
    assert {"partial", "stopped"} <= set(csv_header)


def test_the_cli_says_one_run_failed_and_exits_non_zero(spun_sweep: Path) -> None:
    done = subprocess.run([COSIM, "sweep", str(spun_sweep / "spec.yaml"), "--out",
                           str(spun_sweep), "--resume"], capture_output=True, text=True,
                          timeout=600)
    assert "1 pass, 1 fail" in done.stdout, done.stdout + done.stderr
    assert done.returncode == 3, done.stderr


def _rows(spec_text: str, tmp_path: Path, spin: set[int]) -> tuple:
    """Rows of a two-seed grid, runs ``spin`` stopped by a spin with a small CTE."""
    spec_path = tmp_path / "spec.yaml"
    spec_path.write_text(spec_text)
    spec = load_spec(spec_path)
    rows = []
    for task in spec.tasks():
        stopped = task.run_id in spin
        metrics = {"cte_max_m": 0.01 if stopped else 0.1, "cte_rms_m": 0.05,
                   "completed": not stopped, "outcome": "spun" if stopped else "ok"}
        if stopped:
            metrics["spun_t_s"] = 2.5
        rows.append({"run_id": task.run_id, "point": task.point, "seed": task.seed,
                     "params": dict(task.params), "metrics": metrics, "error": "",
                     "log": "", "started_at": "", "finished_at": ""})
    directory = SweepDir(tmp_path / "out")
    directory.prepare(spec, spec_text, resume=False, n_runs=len(rows))
    return spec, directory, write_tables(directory, spec, rows, len(rows))


GRID = """
scenario: lane-change
seeds: 2
grid: {plant.mass_kg: [1300, 1575], plant.tyre_friction: [0.5, 1.0]}
pass: {cte_max_m: 0.3}
"""


def test_a_cell_with_a_stopped_run_is_a_failure_with_no_value(tmp_path: Path) -> None:
    """One of the two seeds at (1300 kg, 0.5) spun: the cell says so and takes no value
    from either seed; the per-value table's mean leaves the partial run out."""
    spec, directory, flat = _rows(GRID, tmp_path, spin={0})
    cells = grid_cells(spec, flat)
    assert cells is not None
    assert cells.stopped[0][0] == "spun at 2.50 s" and not cells.passed[0][0]
    assert cells.stopped[1][1] == "" and cells.passed[1][1]
    assert heat_map(spec, flat, directory.root / "heat.png") is not None
    summary = summary_markdown(spec, flat, len(flat), [], None)
    assert "**7 of 8 runs pass (87.5 %)**" in summary
    per_value = summary.split("### `plant.mass_kg`")[1].split("###")[0]
    assert "| 1300 | 4 | 3/4 | 0.1 | stopped: spun at 2.50 s |" in per_value


def test_several_stops_in_a_cell_are_counted(tmp_path: Path) -> None:
    spec, _, flat = _rows(GRID, tmp_path, spin={0, 1})
    cells = grid_cells(spec, flat)
    assert cells is not None and cells.stopped[0][0] == "spun: 2 of 2 runs"
    assert math.isnan(cells.value[0][0])


def test_an_ok_outcome_and_a_missing_one_are_no_failure() -> None:
    assert bad_outcome({"outcome": "ok"}) == ""
    assert bad_outcome({}) == ""
    assert bad_outcome({"outcome": "off_road", "off_road_t_s": 4.0}) == "off road at 4.00 s"
    assert bad_outcome({"outcome": "end_of_path"}) == "end of path"


def test_the_league_leaves_a_stopped_run_out_of_its_figures() -> None:
    def row(run_id: int, seed: int, cte: float, outcome: str) -> dict:
        return {"run_id": run_id, "params": {"scenario": "lane-change", "tracker": "pid"},
                "seed": seed, "error": "",
                "metrics": {"cte_max_m": cte, "cte_rms_m": cte / 2, "outcome": outcome,
                            "completed": outcome == "ok", "spun_t_s": 1.0}}

    (entry,) = league([row(0, 0, 0.2, "ok"), row(1, 1, 0.01, "spun")])
    assert entry.values["cte_max_m"] == 0.2 and entry.values["cte_rms_m"] == 0.1
    assert entry.incomplete == 1 and entry.stops == ("spun",)
    assert "pid (1/2 unfinished: spun)" in markdown([entry])


def test_fail_if_says_the_stopped_run_fails_whatever_its_metrics(tmp_path: Path) -> None:
    done = subprocess.run(
        [COSIM, "run", "lane-change", "--tracker", "kinematic-nmpc", "--seed", "5",
         "--set", "plant.mass_kg=1300", "--set", "plant.tyre_friction=0.35",
         "--fail-if", "cte_max_m>0.3", "--out", str(tmp_path / "spun.mcap")],
        capture_output=True, text=True, timeout=600)
    assert done.returncode == 3, done.stderr
    lines = done.stderr.strip().splitlines()
    assert lines[-2].startswith("cosim: run ended badly: outcome spun at t = ")
    assert lines[-1].startswith("cosim: --fail-if 'cte_max_m>0.3': the run fails on its "
                                "outcome spun")
    assert "partial" in lines[-1]


def test_exit_zero_keeps_a_failing_sweep_at_zero(spun_sweep: Path) -> None:
    """The fixture ran with ``--exit-zero`` (0); without it the same sweep exits 3 (above)."""
    done = subprocess.run([COSIM, "sweep", str(spun_sweep / "spec.yaml"), "--out",
                           str(spun_sweep), "--resume", "--exit-zero"], capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "fail the sweep's criteria" not in done.stderr
