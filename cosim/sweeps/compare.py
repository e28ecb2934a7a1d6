"""``cosim compare``: every tracker on every scenario and seed, on one plant, as a league table.

Each (scenario, tracker, seed) is one :class:`~cosim.sweeps.spec.RunTask` run by the sweep's
machinery (:func:`cosim.sweeps.execute.execute_task` on a
:class:`~cosim.sweeps.execute.ProcessBackend`), so every run has the same plant, sensors,
noise and seed as a ``cosim run`` of it; rows are sorted by run id, so the worker count never
shows. The league table has one row per (scenario, tracker): the mean over seeds of each
metric in :data:`LEAGUE_METRICS` (the worst over seeds for maxima), and ``failures``: runs
that did not complete plus control steps that needed a fallback. A run that stopped early
(a spin, leaving the road) has metrics of the part before the stop: they are left out of
the row's figures, and the tracker's name says how many runs stopped and how.

Every closed-loop tracker is meant for every scenario of the library
(:data:`DEFAULT_SCENARIOS`); ``open-loop`` drives the open-loop manoeuvres only and is not
compared. A run that loses the car (a spin) stops there (:mod:`cosim.simulation.outcome`)
and counts as a failure. Measured on the sedan (seed 0, a loaded 2-core machine): on the ISO
3888-1 lane change at 60 km/h the MPCs but ``kinematic-nmpc`` pass every gate, while every
baseline hits at least one (``pid`` and ``lqr`` spin once the steering-rate bound saturates
them); ``dynamic-mpc`` passes up to 68 km/h and hits gates at 72 km/h
(``bench/iso_entry_speed.py``). On the ring circuit ``lqr`` edged out the MPCs when both
NMPCs weighed the steering rate at 3 (seed 0: RMS CTE 0.059 m against 0.077 m for
``dynamic-nmpc``): they lagged the circuit's long changes of curvature, which the LQR,
without a rate penalty, follows. ``dynamic-nmpc``'s own weight is 0.3 since, with the
caution of :mod:`tracker.mpc.caution` (docs/defaults.md).

Outputs in ``--out DIR``: ``league.md`` and ``league.csv`` (the table), ``league.png``
(``cte_rms_m`` per scenario and tracker), ``rows.json`` (every run's metrics),
``rows.jsonl`` (each run's row as it finished, kept if the comparison is interrupted) and
``compare.json`` (what was compared). A folder with files in it is refused unless
``--force`` (start afresh) or ``--resume`` (finish the interrupted comparison it holds). An
interrupt (Ctrl-C, or SIGTERM or SIGINT to the command alone) stops the running runs within
a second (:meth:`cosim.sweeps.execute.ProcessBackend.run`) and writes the league of the
finished ones.
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
from cosim.sweeps.results import bad_outcome, is_partial, read_row_log, refuse_non_empty
from cosim.sweeps.spec import RunTask
from tracker.config import is_plugin_name
from tracker.fmu.config import is_fmu_name

DEFAULT_TRACKERS: tuple[str, ...] = (
    "dynamic-nmpc", "kinematic-nmpc", "ltv-mpc", "dynamic-mpc",
    "pid", "stanley", "pure-pursuit", "lqr",
)
"""Every closed-loop tracker (``open-loop`` drives manoeuvres, not paths)."""

MPC_TRACKERS: frozenset[str] = frozenset(DEFAULT_TRACKERS[:4])
"""The model-predictive trackers."""

BASELINE_TRACKERS: frozenset[str] = frozenset(DEFAULT_TRACKERS[4:])
"""The classic baselines (the rest: trackers from outside cosim, plug-ins and FMUs)."""

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
    incomplete: int = 0
    """Runs that did not reach their end (an error, or ``completed`` false): their metrics
    cover part of the scenario, so they are left out of ``values`` and the row ranks below
    every row whose runs all finished."""
    stops: tuple[str, ...] = ()
    """How its runs that stopped early stopped (``spun``, ``off road`` ...)."""


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
        # A run that stopped early (a spin ...) has metrics of the part before the stop:
        # no measure of the tracker, so its numbers stay out; the row says it stopped.
        whole = [r for r in group if not is_partial(r["metrics"])]
        values = {key: _combine([r["metrics"].get(key) for r in whole], how)
                  for key, _, how in LEAGUE_METRICS}
        failures = sum(1 for r in group if r["error"]) + sum(
            int(r["metrics"].get("solver_failures") or 0) for r in group)
        errors = tuple(sorted({r["error"] for r in group if r["error"]}))
        incomplete = sum(1 for r in group
                         if r["error"] or r["metrics"].get("completed") is False)
        stops = tuple(sorted({bad_outcome(r["metrics"]).split(" at ")[0] for r in group
                              if not r["error"] and is_partial(r["metrics"])}))
        table.append(LeagueRow(scenario, tracker, len(group), values, failures, errors,
                               incomplete, stops))
    return table


def _cell(value: float | None) -> str:
    if value is None:
        return "-"
    return f"{value:.4g}"


def by_scenario(table: Sequence[LeagueRow]) -> dict[str, list[LeagueRow]]:
    """The table's rows per scenario (in run order), each list best RMS CTE first, the
    trackers with runs that did not finish after every tracker whose runs all did."""
    groups: dict[str, list[LeagueRow]] = {}
    for row in table:
        groups.setdefault(row.scenario, []).append(row)
    return {scenario: sorted(rows, key=lambda r: (r.incomplete > 0,
                                                  r.values["cte_rms_m"] is None,
                                                  r.values["cte_rms_m"] or 0.0))
            for scenario, rows in groups.items()}


def _aligned(header: list[str], body: list[list[str]]) -> list[str]:
    """Columns padded to their widest cell: the first left-aligned, the rest right."""
    widths = [max(len(r[i]) for r in [header, *body]) for i in range(len(header))]

    def line(cells: list[str]) -> str:
        return "  ".join(c.ljust(w) if i == 0 else c.rjust(w)
                         for i, (c, w) in enumerate(zip(cells, widths, strict=True))).rstrip()

    return [line(header), *(line(r) for r in body)]


def league_text(table: Sequence[LeagueRow], width: int | None = None) -> str:
    """The league as plain text that fits ``width`` columns (None: no limit, as when
    piped): a row per tracker when that fits, else a row per metric with the trackers as
    columns, else a block per tracker. Every number is shown whole, never cut; a metric no
    run of a scenario has is left out of its section (Markdown and CSV keep every column)."""
    sections = []
    for scenario, rows in by_scenario(table).items():
        # A metric no run of the scenario has (gates off the ISO course) is left out here.
        shown_metrics = [(key, title) for key, title, _ in LEAGUE_METRICS
                         if any(r.values.get(key) is not None for r in rows)]
        keys = [key for key, _ in shown_metrics]
        titles = [title for _, title in shown_metrics]
        wide = _aligned(["tracker", *titles, "failures"],
                        [[shown_name(r), *(_cell(r.values[k]) for k in keys), str(r.failures)]
                         for r in rows])
        tall = _aligned(["metric", *(shown_name(r) for r in rows)],
                        [[title, *(_cell(r.values[key]) for r in rows)]
                         for key, title in zip(keys, titles, strict=True)]
                        + [["failures", *(str(r.failures) for r in rows)]])
        if width is None or max(map(len, wide)) <= width:
            lines = wide
        elif max(map(len, tall)) <= width:
            lines = tall
        else:
            lines = []
            for r in rows:
                lines += [shown_name(r)] + [f"  {line}" for line in _aligned(
                    ["metric", "value"], [[t, _cell(r.values[k])] for k, t in zip(keys, titles,
                                                                          strict=True)]
                    + [["failures", str(r.failures)]])[1:]]
        sections.append("\n".join([scenario, *lines]))
    return "\n\n".join(sections)


def markdown(table: Sequence[LeagueRow]) -> str:
    """The league table as Markdown, one section per scenario, best RMS CTE first."""
    lines = []
    titles = [title for _, title, _ in LEAGUE_METRICS]
    for scenario, rows in by_scenario(table).items():
        lines += [f"## {scenario}", "", "| tracker | " + " | ".join(titles) + " | failures |",
                  "|---" * (len(titles) + 2) + "|"]
        for r in rows:
            cells = [_cell(r.values[key]) for key, _, _ in LEAGUE_METRICS]
            lines.append(f"| {shown_name(r)} | " + " | ".join(cells) + f" | {r.failures} |")
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
    """RMS CTE of every tracker, one panel per scenario: horizontal bars on a linear axis
    from zero (so lengths compare), best first, each labelled with its value; blue bars
    are the MPCs, hatched ones the classic baselines, green ones trackers from outside
    cosim; a pale bar (its label says how many) has runs that did not finish. Scenarios
    differ by orders of magnitude, so each panel has its own scale."""
    import math

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    groups = by_scenario(table)
    columns = 1 if len(groups) <= 3 else 2
    panel_rows = math.ceil(len(groups) / columns)
    trackers = max((len(rows) for rows in groups.values()), default=1)
    figure = Figure(figsize=(6.5 * columns, 0.9 + panel_rows * (0.9 + 0.32 * trackers)),
                    layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(panel_rows, columns, squeeze=False).ravel()
    for ax, (scenario, rows) in zip(axes, groups.items(), strict=False):
        shown = [r for r in rows if r.values["cte_rms_m"] is not None][::-1]  # best on top
        values = [float(r.values["cte_rms_m"] or 0.0) for r in shown]
        bars = ax.barh([shown_name(r) for r in shown], values,
                       color=[_bar_colour(r) for r in shown],
                       hatch=["//" if r.tracker in BASELINE_TRACKERS else "" for r in shown])
        for bar, row in zip(bars, shown, strict=True):
            bar.set_alpha(0.45 if row.incomplete else 1.0)
        ax.bar_label(bars, labels=[f"{v:.3g}" for v in values], padding=3, fontsize=8)
        ax.set_xlim(0.0, 1.18 * max(values, default=1.0) or 1.0)
        ax.set_title(Path(scenario).stem, fontsize=10)
        ax.set_xlabel("RMS cross-track error [m]", fontsize=9)
        ax.grid(True, axis="x", alpha=0.3)
        missing = [r.tracker for r in rows if r.values["cte_rms_m"] is None]
        if missing:
            ax.text(0.99, 0.02, "no value: " + ", ".join(missing), transform=ax.transAxes,
                    ha="right", va="bottom", fontsize=7)
    for ax in axes[len(groups):]:
        ax.set_visible(False)
    figure.suptitle("cosim compare: RMS cross-track error, best on top\n(blue: MPCs; "
                    "hatched: classic baselines; green: from outside cosim; pale: runs that "
                    "did not finish)", fontsize=10)
    figure.savefig(path, dpi=110)


def _bar_colour(row: LeagueRow) -> str:
    if row.tracker in MPC_TRACKERS:
        return "C0"
    return "C1" if row.tracker in BASELINE_TRACKERS else "C2"


def shown_name(row: LeagueRow) -> str:
    """The tracker's label: with how many of its runs did not finish and how they stopped,
    if any (its figures are of the other runs)."""
    name = row.tracker
    if is_fmu_name(name):  # the FMU's file, not its folders (they crowd the chart)
        name = "fmu:" + name.removeprefix("fmu:").replace("\\", "/").rsplit("/", 1)[-1]
    if not row.incomplete:
        return name
    how = f": {', '.join(row.stops)}" if row.stops else ""
    return f"{name} ({row.incomplete}/{row.seeds} unfinished{how})"


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


COMPARE_FILE = "compare.json"
"""In ``--out DIR``: what was compared, so that ``--resume`` finishes the same comparison."""

ROWS_FILE = "rows.jsonl"


class CompareInterrupted(KeyboardInterrupt):
    """A comparison stopped by Ctrl-C or SIGTERM; ``rows`` holds every finished run."""

    def __init__(self, rows: list[dict[str, Any]]) -> None:
        super().__init__()
        self.rows = rows


def non_empty_refusal(out_dir: Path, force: bool, resume: bool) -> None:
    """Refuse an ``--out`` that is a file, or a folder with files in it unless ``force`` or
    ``resume`` (the earlier results would be overwritten or mixed in)."""
    if out_dir.exists() and not out_dir.is_dir():
        raise ConfigError(f"--out {str(out_dir)!r}: is a file: expected a folder")
    if not (force or resume):
        refuse_non_empty(out_dir, "replace its results", "finish the run that wrote them")


def _prepare(out_dir: Path, what: dict[str, Any], force: bool,
             resume: bool) -> dict[int, dict[str, Any]]:
    """Start ``out_dir`` for the comparison ``what``, or (``resume``) read its finished rows."""
    non_empty_refusal(out_dir, force, resume)
    stored = out_dir / COMPARE_FILE
    if resume:
        try:
            earlier = json.loads(stored.read_text())
        except (OSError, ValueError):
            raise ConfigError(f"--resume: {str(out_dir)!r} holds no comparison to finish (no "
                              f"readable {COMPARE_FILE}): expected the --out of an "
                              "interrupted comparison") from None
        if earlier != what:
            raise ConfigError(f"--resume: {str(out_dir)!r} compared {shown_what(earlier)}: "
                              f"expected the same scenarios, trackers, seeds and duration "
                              f"(now {shown_what(what)})")
        return read_row_log(out_dir / ROWS_FILE)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / ROWS_FILE).write_text("")
    stored.write_text(json.dumps(what, indent=1) + "\n")
    return {}


def stored_what(out_dir: Path) -> dict[str, Any] | None:
    """What the comparison in ``out_dir`` compared (its ``compare.json``), if readable."""
    try:
        what = json.loads((out_dir / COMPARE_FILE).read_text())
    except (OSError, ValueError):
        return None
    return what if isinstance(what, dict) else None


def shown_what(what: Any) -> str:
    """A comparison's description in a few words (for messages)."""
    if not isinstance(what, dict):
        return "something else"
    scenarios, trackers = what.get("scenarios", []), what.get("trackers", [])
    duration = what.get("duration_s")
    return (f"{len(scenarios)} scenario(s) x {len(trackers)} tracker(s) x "
            f"{what.get('seeds')} seed(s), "
            + ("each scenario's own duration" if duration is None else f"{duration:g} s"))


def run_compare(scenarios: Sequence[str], trackers: Sequence[str], seeds: int,
                workers: int | None, duration_s: float | None, out_dir: Path | None,
                keep_logs: bool = False, force: bool = False,
                resume: bool = False) -> list[dict[str, Any]]:
    """Run every combination on a process pool with a progress bar; the rows, by run id.

    Each scenario and its course are built once first, and each scenario's config with each
    plug-in or FMU tracker, so a bad name, key, path file or FMU is one error before any run.
    With ``out_dir`` (refused when it holds files, unless
    ``force``, or ``resume`` to run only what an interrupted comparison there left) each row
    is appended to ``out_dir/rows.jsonl`` as one JSON line as it lands (flushed), so an
    interrupt or a crash keeps the finished runs. An interrupt raises
    :class:`CompareInterrupted` with the rows finished so far.
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
    log_dir = out_dir / "logs" if out_dir is not None and keep_logs else None
    tasks = make_tasks(scenarios, trackers, seeds, duration_s, log_dir)
    finished: dict[int, dict[str, Any]] = {}
    rows_path = None
    if out_dir is not None:
        what = {"scenarios": list(scenarios), "trackers": list(trackers), "seeds": seeds,
                "duration_s": duration_s}
        finished = _prepare(out_dir, what, force, resume)
        rows_path = out_dir / ROWS_FILE
    rows = [row for row in finished.values() if row["run_id"] < len(tasks)]
    missing = [task for task in tasks if task.run_id not in finished]
    with RunProgress(len(tasks), len(rows), "compare") as progress:
        def land(row: dict[str, Any]) -> None:
            if row.get("interrupted"):
                return  # not a result: --resume runs it again
            rows.append(row)
            if rows_path is not None:
                with rows_path.open("a") as handle:
                    handle.write(json.dumps(row) + "\n")
            progress.update(row, "error" if row["error"] else "ok")

        try:
            ProcessBackend(workers or default_workers()).run(missing, land)
        except KeyboardInterrupt:
            raise CompareInterrupted(sorted(rows, key=lambda r: r["run_id"])) from None
    return sorted(rows, key=lambda r: r["run_id"])
