"""``cosim compare``: every tracker on every scenario and seed, on one plant, as a league table.

Each (scenario, tracker, seed) is one :class:`~cosim.sweeps.spec.RunTask` run by the sweep's
machinery (:func:`cosim.sweeps.execute.execute_task` on a
:class:`~cosim.sweeps.execute.ProcessBackend`), so every run has the same plant, sensors,
noise and seed as a ``cosim run`` of it; rows are sorted by run id, so the worker count never
shows. The league table has one row per (scenario, tracker): the mean over seeds of each
metric in :data:`LEAGUE_METRICS` (the worst over seeds for maxima), and ``failures``: runs
that did not complete plus control steps that needed a fallback.

Every closed-loop tracker is meant for every scenario of the library (:data:`DEFAULT_SCENARIOS`);
``open-loop`` drives the open-loop manoeuvres only and is not compared. A run that loses the
car (a spin) still completes and shows as a large CTE, a gate hit or a track exit; only a run
that did not complete counts as a failure. Measured on the sedan (seed 0, a loaded 2-core
machine): on the ISO 3888-1 lane change at 60 km/h the MPCs but ``kinematic-nmpc`` pass every
gate, while every baseline hits at least one (``pid`` and ``lqr`` spin once the steering-rate
bound saturates them); ``dynamic-mpc`` passes up to 68 km/h and hits gates at 72 km/h
(``bench/iso_entry_speed.py``). On the ring circuit ``lqr`` edges out the MPCs (seed 0,
quiet machine: RMS CTE 0.059 m against 0.077 m for ``dynamic-nmpc``, the best MPC): their
steering-rate weight (``tracker.weights.steer_rate = 3``, tuned for the lane change's
comfort) makes them lag the circuit's long changes of curvature, which the LQR, without a
rate penalty, follows. With ``tracker.weights.steer_rate=0.3`` ``dynamic-nmpc`` gives
0.053 m, with ``tracker.weights.cte=100`` 0.051 m, both ahead of the LQR.

Outputs in ``--out DIR``: ``league.md`` and ``league.csv`` (the table), ``league.png``
(``cte_rms_m`` per scenario and tracker, log scale), ``rows.json`` (every run's metrics) and
``rows.jsonl`` (each run's row as it finished, kept if the comparison is interrupted).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cosim.core.exceptions import ConfigError
from cosim.sweeps.spec import RunTask
from tracker.config import is_plugin_name
from tracker.fmu.config import is_fmu_name

DEFAULT_TRACKERS: tuple[str, ...] = (
    "dynamic-nmpc", "kinematic-nmpc", "ltv-mpc", "dynamic-mpc",
    "pid", "stanley", "pure-pursuit", "lqr",
)
"""Every closed-loop tracker (``open-loop`` drives manoeuvres, not paths)."""

MPC_TRACKERS: frozenset[str] = frozenset(DEFAULT_TRACKERS[:4])
"""The model-predictive trackers, the rest being the classic baselines."""

DEFAULT_SCENARIOS: tuple[str, ...] = (
    "lane-change", "iso-lane-change", "circle", "figure-eight", "slalom", "s-curve",
    "stop-and-go", "track",
)
"""The closed-loop scenarios of the library (the open-loop manoeuvres are left out)."""

LEAGUE_METRICS: tuple[tuple[str, str, str], ...] = (
    ("cte_max_m", "max CTE [m]", "max"),
    ("cte_rms_m", "RMS CTE [m]", "mean"),
    ("heading_err_max_rad", "max heading err [rad]", "max"),
    ("speed_err_rms_mps", "RMS speed err [m/s]", "mean"),
    ("lat_accel_max_mps2", "max a_y [m/s^2]", "max"),
    ("jerk_rms_mps3", "RMS jerk [m/s^3]", "mean"),
    ("solve_ms_p50", "solve p50 [ms]", "mean"),
    ("solve_ms_p99", "solve p99 [ms]", "max"),
    ("step_ms_p50", "step p50 [ms]", "mean"),
    ("step_ms_p99", "step p99 [ms]", "max"),
    ("gates_hit", "gates hit", "max"),
    ("track_limit_exceedances", "track exits", "max"),
)
"""(metric key, column title, how seeds combine)."""


@dataclass(frozen=True)
class LeagueRow:
    """One (scenario, tracker) of the table: combined metrics over its seeds."""

    scenario: str
    tracker: str
    seeds: int
    values: dict[str, float | None]
    failures: int
    errors: tuple[str, ...]


def parse_names(text: str | None, default: Sequence[str], known: Sequence[str] | None,
                what: str) -> tuple[str, ...]:
    """A comma-separated list; each name checked against ``known`` when given."""
    if text is None:
        return tuple(default)
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    if not names:
        raise ConfigError(f"--{what} {text!r}: expected a comma-separated list of names")
    if known is not None:
        for name in names:
            if name not in known:
                raise ConfigError(f"--{what}: {name!r} is not one of {', '.join(known)}")
    return names


def make_tasks(scenarios: Sequence[str], trackers: Sequence[str], seeds: int,
               duration_s: float | None, log_dir: Path | None) -> list[RunTask]:
    """One task per (scenario, tracker, seed), scenario-major; seeds 0 .. seeds-1."""
    tasks = []
    for i, scenario in enumerate(scenarios):
        for j, tracker in enumerate(trackers):
            for seed in range(seeds):
                run_id = len(tasks)
                log = None
                if log_dir is not None:
                    log = str(log_dir / f"{Path(scenario).stem}-{tracker}-seed{seed}.mcap")
                tasks.append(RunTask(
                    run_id=run_id, point=i * len(trackers) + j, seed=seed,
                    params=(("scenario", scenario), ("tracker", tracker)),
                    scenario=scenario, overrides=(), tracker=tracker, estimator=None,
                    duration_s=duration_s, log_path=log))
    return tasks


def _combine(values: list[float], how: str) -> float | None:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    if not finite:
        return None
    return max(finite) if how == "max" else sum(finite) / len(finite)


def league(rows: Sequence[dict[str, Any]]) -> list[LeagueRow]:
    """The table from the runs' rows (:func:`cosim.sweeps.execute.execute_task`)."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in sorted(rows, key=lambda r: r["run_id"]):
        params = dict(row["params"])
        groups.setdefault((params["scenario"], params["tracker"]), []).append(row)
    table = []
    for (scenario, tracker), group in groups.items():
        values = {key: _combine([r["metrics"].get(key) for r in group], how)
                  for key, _, how in LEAGUE_METRICS}
        failures = sum(1 for r in group if r["error"]) + sum(
            int(r["metrics"].get("solver_failures") or 0) for r in group)
        errors = tuple(sorted({r["error"] for r in group if r["error"]}))
        table.append(LeagueRow(scenario, tracker, len(group), values, failures, errors))
    return table


def _cell(value: float | None) -> str:
    if value is None:
        return "-"
    return f"{value:.4g}"


def by_scenario(table: Sequence[LeagueRow]) -> dict[str, list[LeagueRow]]:
    """The table's rows per scenario (in run order), each list best RMS CTE first."""
    groups: dict[str, list[LeagueRow]] = {}
    for row in table:
        groups.setdefault(row.scenario, []).append(row)
    return {scenario: sorted(rows, key=lambda r: (r.values["cte_rms_m"] is None,
                                                  r.values["cte_rms_m"] or 0.0))
            for scenario, rows in groups.items()}


def markdown(table: Sequence[LeagueRow]) -> str:
    """The league table as Markdown, one section per scenario, best RMS CTE first."""
    lines = []
    titles = [title for _, title, _ in LEAGUE_METRICS]
    for scenario, rows in by_scenario(table).items():
        lines += [f"## {scenario}", "", "| tracker | " + " | ".join(titles) + " | failures |",
                  "|---" * (len(titles) + 2) + "|"]
        for r in rows:
            cells = [_cell(r.values[key]) for key, _, _ in LEAGUE_METRICS]
            lines.append(f"| {r.tracker} | " + " | ".join(cells) + f" | {r.failures} |")
        lines.append("")
    return "\n".join(lines)


def write_csv(table: Sequence[LeagueRow], path: Path) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["scenario", "tracker", "seeds",
                         *[key for key, _, _ in LEAGUE_METRICS], "failures"])
        for r in table:
            writer.writerow([r.scenario, r.tracker, r.seeds,
                             *["" if r.values[k] is None else r.values[k]
                               for k, _, _ in LEAGUE_METRICS], r.failures])


def write_chart(table: Sequence[LeagueRow], path: Path) -> None:
    """Grouped bars of RMS CTE: one group per scenario, one bar per tracker (log scale)."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    scenarios = list(dict.fromkeys(r.scenario for r in table))
    trackers = list(dict.fromkeys(r.tracker for r in table))
    figure = Figure(figsize=(max(6.0, 1.4 * len(scenarios) + 2.0), 4.5))
    FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    width = 0.8 / max(1, len(trackers))
    lookup = {(r.scenario, r.tracker): r.values["cte_rms_m"] for r in table}
    for k, tracker in enumerate(trackers):
        heights = [lookup.get((s, tracker)) or np.nan for s in scenarios]
        hatch = "" if tracker in MPC_TRACKERS else "//"
        ax.bar(np.arange(len(scenarios)) + (k - (len(trackers) - 1) / 2) * width, heights,
               width, label=tracker, hatch=hatch)
    ax.set_xticks(np.arange(len(scenarios)), [Path(s).stem for s in scenarios],
                  rotation=20, ha="right")
    ax.set_yscale("log")
    ax.set_ylabel("RMS cross-track error [m]")
    ax.set_title("cosim compare: RMS CTE per scenario (hatched: classic baselines)")
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.legend(fontsize="small", ncol=2)
    figure.tight_layout()
    figure.savefig(path, dpi=110)


def json_rows(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """``--json``: ``{scenario, tracker, seed, metrics}`` per run (plus ``error`` if any)."""
    out = []
    for row in sorted(rows, key=lambda r: r["run_id"]):
        params = dict(row["params"])
        item = {"scenario": params["scenario"], "tracker": params["tracker"],
                "seed": row["seed"], "metrics": row["metrics"]}
        if row["error"]:
            item["error"] = row["error"]
        out.append(item)
    return out


def write_outputs(rows: Sequence[dict[str, Any]], out_dir: Path) -> list[LeagueRow]:
    out_dir.mkdir(parents=True, exist_ok=True)
    table = league(rows)
    (out_dir / "league.md").write_text(markdown(table))
    write_csv(table, out_dir / "league.csv")
    write_chart(table, out_dir / "league.png")
    (out_dir / "rows.json").write_text(json.dumps(json_rows(rows), indent=1))
    return table


def run_compare(scenarios: Sequence[str], trackers: Sequence[str], seeds: int,
                workers: int | None, duration_s: float | None, log_dir: Path | None,
                rows_path: Path | None = None) -> list[dict[str, Any]]:
    """Run every combination on a process pool with a progress bar; the rows, by run id.

    Each scenario and its course are built once first, and each scenario's config with each
    plug-in or FMU tracker, so a bad name, key, path file or FMU is one error before any run.
    With ``rows_path`` each row is appended to it as one JSON line as it lands (flushed), so
    an interrupt or a crash keeps the finished runs.
    """
    from cosim.simulation.runner import scenario_course
    from cosim.simulation.scenario_config import load_config
    from cosim.sweeps.driver import RunProgress
    from cosim.sweeps.execute import ProcessBackend, default_workers

    if seeds < 1:
        raise ConfigError(f"--seeds {seeds}: expected at least 1")
    for scenario in scenarios:
        scenario_course(load_config(scenario, duration_s=duration_s))
        for tracker in trackers:  # a bad plug-in or FMU: one error before any run
            if is_plugin_name(tracker) or is_fmu_name(tracker):
                load_config(scenario, duration_s=duration_s, tracker=tracker)
    tasks = make_tasks(scenarios, trackers, seeds, duration_s, log_dir)
    rows: list[dict[str, Any]] = []
    if rows_path is not None:
        rows_path.parent.mkdir(parents=True, exist_ok=True)
        rows_path.write_text("")
    with RunProgress(len(tasks), 0, "compare") as progress:
        def land(row: dict[str, Any]) -> None:
            rows.append(row)
            if rows_path is not None:
                with rows_path.open("a") as handle:
                    handle.write(json.dumps(row) + "\n")
            progress.update(row, "error" if row["error"] else "ok")

        ProcessBackend(workers or default_workers()).run(tasks, land)
    return sorted(rows, key=lambda r: r["run_id"])
