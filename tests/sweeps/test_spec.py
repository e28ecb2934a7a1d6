"""Sweep specs, tables, summary and plots without running a simulation."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from cosim.core.exceptions import ConfigError, CosimError
from cosim.simulation.scenario_config import parse_override
from cosim.sweeps.execute import execute_task
from cosim.sweeps.plots import heat_map, metric_plots
from cosim.sweeps.results import SweepDir, bounds, low_is_bad, summary_markdown, write_tables
from cosim.sweeps.spec import load_spec, override_text, unit_of


def write_spec(tmp_path: Path, text: str, name: str = "spec.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


GRID_SPEC = """
scenario: lane-change
duration_s: 1
seeds: 2
set: {sensors.gnss.sigma_m: 0.05}
grid:
  plant.mass_kg: [1100, 1575, 2050]
  plant.tyre_friction: [0.7, 1.0]
pass: {cte_max_m: 0.3, completed: true}
"""


def test_grid_is_full_factorial_point_major_seed_minor(tmp_path: Path) -> None:
    spec = load_spec(write_spec(tmp_path, GRID_SPEC))
    tasks = spec.tasks()
    assert len(tasks) == 3 * 2 * 2
    assert [t.run_id for t in tasks] == list(range(12))
    assert [(t.point, t.seed) for t in tasks[:4]] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert tasks[2].params == (("plant.mass_kg", 1100), ("plant.tyre_friction", 1.0))
    assert tasks[2].overrides == ("sensors.gnss.sigma_m=0.05", "plant.mass_kg=1100",
                                  "plant.tyre_friction=1.0")
    mass = spec.parameters[0]
    assert (mass.nominal, mass.unit) == (1575.0, "kg")
    assert (mass.counterpart, mass.counterpart_value) == ("tracker.model.mass_kg", 1575.0)
    assert spec.metric == "cte_max_m"
    assert (spec.tracker_name, spec.estimator_name) == ("dynamic-nmpc", "ekf")


def test_random_sampling_is_seeded_and_inside_the_range(tmp_path: Path) -> None:
    text = """
scenario: lane-change
seeds: [3]
random: {n: 5, seed: 11, plant.mass_kg: [1200, 1900], sensors.gnss.sigma_m: [0.01, 0.5]}
"""
    first = load_spec(write_spec(tmp_path, text)).points()
    again = load_spec(write_spec(tmp_path, text)).points()
    other = load_spec(write_spec(tmp_path, text.replace("seed: 11", "seed: 12"))).points()
    assert first == again
    assert first != other
    assert len(first) == 5
    for mass, sigma in first:
        assert 1200 <= mass <= 1900 and 0.01 <= sigma <= 0.5


def test_spec_hash_follows_the_content(tmp_path: Path) -> None:
    one = load_spec(write_spec(tmp_path, GRID_SPEC))
    same = load_spec(write_spec(tmp_path, "# a comment changes nothing\n" + GRID_SPEC))
    other = load_spec(write_spec(tmp_path, GRID_SPEC.replace("2050", "2000")))
    assert one.digest() == same.digest()
    assert one.digest() != other.digest()


@pytest.mark.parametrize("value", [1e-5, 0.1, 2047.5, 3, True, "ukf", [1, 2]])
def test_override_text_reads_back_exactly(value: object) -> None:
    key, parsed = parse_override(override_text("a.b", value))
    assert (key, parsed) == ("a.b", value)


def test_units_come_from_the_key_names() -> None:
    assert [unit_of(k) for k in ("plant.mass_kg", "plant.actuator_delay_s",
                                  "sensors.gnss.sigma_m", "plant.tyre_friction",
                                  "tracker.model.cornering_stiffness_front_npr")] == \
        ["kg", "s", "m", "-", "N/rad"]


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("scenario: lane-change\ngrid: {plant.mas_kg: [1]}",
         "'plant.mas_kg': unknown dotted path"),
        ("scenario: lane-change\ngrid: {}", "grid: empty"),
        ("scenario: lane-change\ngrid: {plant.mass_kg: []}", "expected a non-empty list"),
        ("scenario: lane-change\nrandom: {n: 3, plant.mass_kg: [2000, 1000]}",
         "[2000, 1000]: expected low <= high"),
        ("scenario: lane-change\npass: {cte_maxx_m: 1}", "unknown metric 'cte_maxx_m'"),
        ("scenario: lane-change\ngrid: {plant.mass_kg: [-1]}", "plant.mass_kg = -1"),
        ("scenario: lane-change\nseeds: 0", "seeds: 0"),
        ("scenario: lane-change\ngirdd: {}", "unknown key 'girdd'"),
        ("scenario: acc-braking\npass: {gap_min_m: 5}",
         "gap_min_m is a minimum: expected {min: 5} (at least) or {max: 5} (at most)"),
        ("scenario: acc-braking\npass: {gap_min_m: {least: 5}}",
         "expected {min: X}, {max: Y} or both"),
        ("scenario: acc-braking\npass: {gap_min_m: {min: 5, max: 2}}", "expected min <= max"),
        ("scenario: lane-change\npass: {outcome: ok}", "a word, not a number"),
        ("scenario: lane-change\npass: {gap_mn_m: {min: 5}}", "did you mean gap_min_m?"),
        ("scenario: lane-change\nset: {plant.mass_kg: 1300}\ngrid: {plant.mass_kg: [1200]}",
         "also fixed"),
        ("scenario: lane-change\npass: {completed: 1}", "completed: 1: expected true or false"),
    ],
)
def test_bad_spec_names_the_bad_value(tmp_path: Path, text: str, fragment: str) -> None:
    with pytest.raises(ConfigError) as error:
        load_spec(write_spec(tmp_path, text))
    assert fragment in str(error.value)
    assert "\n" not in str(error.value)


def test_resume_refuses_another_spec(tmp_path: Path) -> None:
    spec = load_spec(write_spec(tmp_path, GRID_SPEC))
    directory = SweepDir(tmp_path / "out")
    directory.prepare(spec, GRID_SPEC, resume=False, n_runs=12)
    with pytest.raises(CosimError, match="already holds a sweep"):
        directory.prepare(spec, GRID_SPEC, resume=False, n_runs=12)
    directory.prepare(spec, GRID_SPEC, resume=True, n_runs=12)  # same spec: fine
    other = load_spec(write_spec(tmp_path, GRID_SPEC.replace("seeds: 2", "seeds: 3")))
    with pytest.raises(CosimError, match="the spec changed"):
        directory.prepare(other, GRID_SPEC, resume=True, n_runs=18)
    with pytest.raises(CosimError, match="no sweep to resume"):
        SweepDir(tmp_path / "empty").prepare(spec, GRID_SPEC, resume=True, n_runs=12)


def test_a_run_that_cannot_start_is_a_row_with_its_error(tmp_path: Path) -> None:
    spec = load_spec(write_spec(tmp_path, GRID_SPEC))
    task = spec.tasks()[0]
    bad = type(task)(**{**task.__dict__, "overrides": ("plant.no_such_key=1",)})
    row = execute_task(bad)
    assert row["run_id"] == 0 and row["metrics"] == {} and not row["interrupted"]
    assert row["error"].startswith("ConfigError: unknown key 'plant.no_such_key'")
    json.dumps(row, allow_nan=False)  # plain data


def fake_rows(spec_tasks: list) -> list[dict]:
    """Rows as workers return them: CTE grows as friction drops; one run errored."""
    rows = []
    for task in spec_tasks:
        params = dict(task.params)
        cte = 0.05 * params["plant.mass_kg"] / 1575 / params["plant.tyre_friction"] ** 6
        metrics = {"cte_max_m": cte, "completed": True, "nees_mean": math.nan}
        rows.append({"run_id": task.run_id, "point": task.point, "seed": task.seed,
                     "params": params, "metrics": metrics, "error": "", "log": "",
                     "started_at": "", "finished_at": ""})
    rows[0].update(metrics={}, error="PhysicsDivergenceError: non-finite state")
    return rows


def test_tables_summary_and_plots_from_rows(tmp_path: Path) -> None:
    spec = load_spec(write_spec(tmp_path, GRID_SPEC))
    directory = SweepDir(tmp_path / "out")
    directory.prepare(spec, GRID_SPEC, resume=False, n_runs=12)
    rows = fake_rows(spec.tasks())
    flat = write_tables(directory, spec, list(reversed(rows)), 12)
    assert [r["run_id"] for r in flat] == list(range(12))
    document = json.loads((directory.root / "results.json").read_text())
    assert document["passed"] == sum(r["pass"] for r in flat) == 7  # 1 error, 4 over 0.3 m
    assert document["rows"][0]["error"].startswith("PhysicsDivergenceError")
    assert document["rows"][1]["nees_mean"] is None
    header = (directory.root / "results.csv").read_text().splitlines()[0].split(",")
    assert header[:6] == ["run_id", "point", "seed", "plant.mass_kg", "plant.tyre_friction",
                          "pass"]
    heat = heat_map(spec, flat, directory.root / "heat.png")
    plots = metric_plots(spec, flat, directory.root)
    assert heat is not None and heat.stat().st_size > 10_000
    assert [p.name for p in plots] == ["cte_max_m-vs-plant.mass_kg.png",
                                       "cte_max_m-vs-plant.tyre_friction.png"]
    summary = summary_markdown(spec, flat, 12, [heat, *plots], 1.0)
    assert "**7 of 12 runs pass (58.3 %)**" in summary
    assert "`tracker.model.mass_kg` = 1575 (held)" in summary
    assert "| 1 | 1 | 1/1 |" not in summary  # aggregates count every seed and point
    worst_table = summary.split("## Worst cases")[1]
    assert worst_table.splitlines()[4].startswith("| 0 | 1100 | 0.7 | 0 | n/a | - | **FAIL**")


GAP_SPEC = """
scenario: acc-braking
duration_s: 1
seeds: 2
grid:
  traffic.lead.brake_decel_mps2: [6, 9]
  tracker.acc.time_gap_s: [1.0, 1.5]
pass: {gap_min_m: {min: 2}}
"""


def test_the_worst_of_a_minimum_is_the_smallest(tmp_path: Path) -> None:
    """For ``gap_min_m`` the worst run is the closest one: the summary lists it first, and
    the per-value and per-cell figures are the smallest gap, not the largest."""
    spec = load_spec(write_spec(tmp_path, GAP_SPEC))
    rows = []
    for task in spec.tasks():
        params = dict(task.params)
        gap = 12.0 - params["traffic.lead.brake_decel_mps2"] + 4.0 * params[
            "tracker.acc.time_gap_s"] - 0.5 * task.seed
        rows.append({"run_id": task.run_id, "point": task.point, "seed": task.seed,
                     "params": params, "metrics": {"gap_min_m": gap, "completed": True},
                     "error": "", "log": "", "started_at": "", "finished_at": ""})
    directory = SweepDir(tmp_path / "out")
    directory.prepare(spec, GAP_SPEC, resume=False, n_runs=len(rows))
    flat = write_tables(directory, spec, rows, len(rows))
    smallest = min(r["gap_min_m"] for r in flat)
    summary = summary_markdown(spec, flat, len(rows), [], 1.0)
    first_row = summary.split("## Worst cases")[1].splitlines()[4]
    assert f"| {smallest:.4g} |" in first_row, first_row
    per_value = summary.split("### `traffic.lead.brake_decel_mps2`")[1].split("###")[0]
    assert per_value.splitlines()[-2].endswith(f"| {smallest:.4g} |"), per_value
    grid = summary.split("## Worst `gap_min_m` per grid point")[1].split("##")[0]
    assert f"{smallest:.4g}" in grid and f"{max(r['gap_min_m'] for r in flat):.4g}" \
        not in grid


def test_a_minimum_metric_takes_a_lower_bound(tmp_path: Path) -> None:
    """Traffic and course metrics are criteria too; ``{min: X}`` is a lower bound."""
    spec = load_spec(write_spec(tmp_path, "scenario: acc-braking\nduration_s: 1\n"
                                "pass: {gap_min_m: {min: 5}, ttc_min_s: {min: 2, max: 99}, "
                                "safe_gap_ok: true}\n"))
    gap, ttc, safe = spec.criteria
    assert gap.describe() == "gap_min_m >= 5 m"
    assert gap.failure({"gap_min_m": 4.5}) == "gap_min_m=4.5<5"
    assert gap.failure({"gap_min_m": 12.0}) is None
    assert ttc.failure({"ttc_min_s": 100.0}) == "ttc_min_s=100>99"
    assert safe.failure({"safe_gap_ok": False}) == "safe_gap_ok=false"
    assert spec.metric == "gap_min_m"
    assert "Infinity" not in json.dumps(spec.to_dict())


def test_several_metrics_are_plotted_and_a_lower_bound_is_drawn(tmp_path: Path) -> None:
    spec = load_spec(write_spec(tmp_path, "scenario: acc-braking\nduration_s: 1\n"
                                "grid: {traffic.lead.brake_decel_mps2: [3, 6, 9]}\n"
                                "pass: {gap_min_m: {min: 2}}\n"
                                "metric: [gap_min_m, ttc_min_s]\n"))
    assert spec.metric == "gap_min_m" and spec.metrics == ("gap_min_m", "ttc_min_s")
    assert bounds(spec, "gap_min_m") == (2.0, None)
    assert low_is_bad(spec, "gap_min_m") and low_is_bad(spec, "ttc_min_s")
    assert not low_is_bad(spec, "cte_max_m")
    flat = [{"traffic.lead.brake_decel_mps2": decel, "gap_min_m": gap, "ttc_min_s": ttc,
             "pass": ok, "error": "", "outcome": outcome}
            for decel, gap, ttc, ok, outcome in ((3, 2.4, 2.7, True, "ok"),
                                                 (6, 1.2, 1.4, False, "ok"),
                                                 (9, 0.0, 0.0, False, "collision"))]
    paths = metric_plots(spec, flat, tmp_path)
    assert [p.name for p in paths] == ["gap_min_m-vs-traffic.lead.brake_decel_mps2.png",
                                       "ttc_min_s-vs-traffic.lead.brake_decel_mps2.png"]
    assert all(p.stat().st_size > 10_000 for p in paths)
    with pytest.raises(ConfigError, match=r"metric: \[\]"):
        load_spec(write_spec(tmp_path, "scenario: acc-braking\nmetric: []\n", "empty.yaml"))


def test_a_sweep_run_records_its_end_of_run_warnings_in_its_row(tmp_path: Path) -> None:
    """A sweep worker's run does not print the belief check's warning (every run of a sweep
    would): the row's metrics carry it."""
    import warnings

    from cosim.simulation.belief_check import BeliefMismatchWarning

    spec = load_spec(write_spec(tmp_path, "scenario: lane-change\nduration_s: 3\nseeds: 1\n"
                                "set: {sensors.gnss.sigma_m: 0.3}\n"))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        row = execute_task(spec.tasks()[0])
    assert row["metrics"]["belief_mismatches"] >= 1
    assert not [w for w in seen if issubclass(w.category, BeliefMismatchWarning)]
