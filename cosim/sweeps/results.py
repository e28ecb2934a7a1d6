"""A sweep's output directory: the append-only row log, resume, tables and the summary.

Layout of ``--out DIR``::

    sweep.json      the spec as resolved, its hash, cosim's version, the number of runs
    spec.yaml       the spec file as given
    results.jsonl   one raw row per finished run, appended (and flushed) as each finishes
    results.csv     one flat row per run, sorted by run id
    results.json    the same rows plus the sweep's description, pass rate and headline metric
    summary.md      what was varied, pass rate, worst cases, per-value aggregates, plots
    *.png           plots (:mod:`cosim.sweeps.plots`)
    logs/           run-NNNN.mcap, one per run, with --keep-logs

``results.jsonl`` is the record of truth: a killed sweep loses at most the runs in flight,
and ``--resume`` reads it back (a half-written last line is ignored) and runs only the
missing run ids. The other files are derived from it and rewritten at the end.
"""

from __future__ import annotations

import collections
import csv
import json
import math
import os
import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from cosim.core.exceptions import CosimError
from cosim.simulation.metric_keys import METRIC_KEYS
from cosim.sweeps.spec import Parameter, SweepSpec, axis_label, unit_of

SWEEP_FILE = "sweep.json"
ROWS_FILE = "results.jsonl"
WORST_CASES = 10
"""Rows in the summary's worst-case table."""
RANDOM_BINS = 4
"""A random sweep's per-parameter aggregates group the values into this many equal bins."""


def read_row_log(path: Path) -> dict[int, dict[str, Any]]:
    """The finished rows of a row log (JSON lines) by run id; a torn or damaged line and an
    interrupted run's row are skipped (``--resume`` runs them again)."""
    rows: dict[int, dict[str, Any]] = {}
    if not path.is_file():
        return rows
    for line in path.read_bytes().splitlines():
        try:
            row = json.loads(line.decode("utf-8"))
        except ValueError:  # UnicodeDecodeError included
            continue  # a line a kill or a full disk cut short, or damaged: run it again
        if isinstance(row, dict) and isinstance(row.get("run_id"), int) \
                and not row.get("interrupted"):
            rows[row["run_id"]] = row
    return rows


def refuse_non_empty(out: Path, force_does: str, resume_does: str) -> None:
    """Refuse ``--out`` naming a folder with files in it (their results would be overwritten
    or mixed in); the message says what ``--force`` and ``--resume`` would do instead."""
    if not out.is_dir():
        return
    entries = sorted(p.name for p in out.iterdir())
    if entries:
        names = ", ".join(entries[:3]) + (" ..." if len(entries) > 3 else "")
        raise CosimError(f"--out {str(out)!r}: not empty ({names}): expected a new or empty "
                         f"folder (or --force to {force_does}, --resume to {resume_does})")


@dataclass(frozen=True)
class SweepDir:
    """The paths of one sweep's output directory."""

    root: Path

    @property
    def sweep_file(self) -> Path:
        return self.root / SWEEP_FILE

    @property
    def rows_file(self) -> Path:
        return self.root / ROWS_FILE

    @property
    def log_dir(self) -> Path:
        return self.root / "logs"

    def prepare(self, spec: SweepSpec, spec_text: str, resume: bool, n_runs: int,
                force: bool = False) -> None:
        """Start a new sweep here, or check that ``--resume`` continues the same spec.

        A directory that already holds a sweep is not overwritten: without ``--resume``
        it is refused (unless ``force``: its rows are dropped and the sweep starts afresh),
        with ``--resume`` its spec hash must match this spec's.
        """
        digest = spec.digest()
        if self.sweep_file.is_file() and force and not resume:
            self.rows_file.unlink(missing_ok=True)
            self.sweep_file.unlink()
        if self.sweep_file.is_file():
            if not resume:
                raise CosimError(
                    f"--out {str(self.root)!r}: already holds a sweep ({SWEEP_FILE}): expected "
                    "a new directory, or --resume to finish that sweep")
            try:
                stored = json.loads(self.sweep_file.read_text())["spec_hash"]
            except (OSError, ValueError, KeyError, TypeError):
                raise CosimError(f"--resume: {str(self.sweep_file)!r} is unreadable: expected "
                                 "the sweep.json a sweep writes") from None
            if stored != digest:
                raise CosimError(
                    f"--resume: the spec changed since the sweep in {str(self.root)!r} started "
                    f"(spec hash {stored[:12]}, now {digest[:12]}): expected the same spec, "
                    "or a new --out")
            return
        if resume:
            raise CosimError(f"--resume: {str(self.root)!r} holds no sweep to resume (no "
                             f"{SWEEP_FILE}): expected the --out of an interrupted sweep")
        from cosim import __version__

        self.root.mkdir(parents=True, exist_ok=True)
        (self.root / "spec.yaml").write_text(spec_text)
        document = {"spec_hash": digest, "cosim_version": __version__, "runs": n_runs,
                    "spec": spec.to_dict()}
        self.sweep_file.write_text(json.dumps(document, indent=2) + "\n")

    def read_rows(self) -> dict[int, dict[str, Any]]:
        """The finished rows of ``results.jsonl`` by run id (a torn last line is skipped)."""
        return read_row_log(self.rows_file)

    def open_rows(self) -> IO[str]:
        """``results.jsonl`` for appending; a torn last line is ended first."""
        if self.rows_file.is_file():
            with self.rows_file.open("rb+") as raw:
                raw.seek(0, os.SEEK_END)
                if raw.tell() > 0:
                    raw.seek(-1, os.SEEK_END)
                    if raw.read(1) != b"\n":
                        raw.write(b"\n")
        return self.rows_file.open("a", encoding="utf-8")


def append_row(handle: IO[str], row: dict[str, Any]) -> None:
    """Append one row as a JSON line and push it to the disk before the next run ends."""
    handle.write(json.dumps(row, allow_nan=False) + "\n")
    handle.flush()
    os.fsync(handle.fileno())


def bad_outcome(metrics: dict[str, Any]) -> str:
    """How a run's outcome falls short, in words (``"spun at 3.07 s"``), or ``""`` for an
    ``ok`` run (or a row without metrics: an error says why instead).

    A run whose outcome is not ``ok`` fails every criterion: a spin, a rollover, leaving the
    road, a collision or reaching the end of the path is not tracking, whatever the metrics
    of the part before it say. The time is the event's (``<outcome>_t_s``)."""
    outcome = metrics.get("outcome")
    if not isinstance(outcome, str) or outcome == "ok":
        return ""
    when = metrics.get(f"{outcome}_t_s")
    shown = outcome.replace("_", " ")
    if isinstance(when, (int, float)) and not isinstance(when, bool) and math.isfinite(when):
        return f"{shown} at {when:.2f} s"
    return shown


def is_partial(metrics: dict[str, Any]) -> bool:
    """Whether a run's metrics cover only part of it: it stopped before its end (a spin, an
    abort), so ``cte_max_m`` and the rest describe the time up to the stop, not the run."""
    return metrics.get("completed") is False


def failures(row: dict[str, Any], spec: SweepSpec) -> list[str]:
    """Why a row fails: its error; its outcome when that is not ``ok`` (first: the run is a
    failure whatever its metrics, :func:`bad_outcome`); each criterion it misses. Empty: it
    passes."""
    if row.get("error"):
        return [str(row["error"])]
    metrics = row.get("metrics", {})
    outcome = bad_outcome(metrics)
    missed = [f for c in spec.criteria if (f := c.failure(metrics)) is not None]
    if outcome:
        partial = " (metrics up to the stop)" if is_partial(metrics) else ""
        return [f"outcome {outcome}{partial}", *missed]
    return missed


def flat_row(row: dict[str, Any], spec: SweepSpec, metric_keys: Sequence[str]
             ) -> dict[str, Any]:
    """One table row: run id, point, seed, varied values, pass, why not, error, outcome,
    whether its metrics are partial (the run stopped early) and how it stopped, metrics."""
    why = failures(row, spec)
    flat: dict[str, Any] = {"run_id": row["run_id"], "point": row["point"], "seed": row["seed"]}
    flat.update({p.path: row["params"].get(p.path) for p in spec.parameters})
    flat["pass"] = not why
    flat["failed"] = "" if row.get("error") else "; ".join(why)
    flat["error"] = row.get("error", "")
    metrics = row.get("metrics", {})
    flat["outcome"] = metrics.get("outcome", "")
    flat["mismatch"] = "; ".join(row.get("mismatch", []))
    # A run that stopped early: its metrics cover the time up to the stop (how and when).
    flat["partial"] = is_partial(metrics) and not row.get("error")
    flat["stopped"] = bad_outcome(metrics) if flat["partial"] else ""
    flat.update({key: _finite_or_none(metrics.get(key)) for key in metric_keys})
    flat.update({key: row.get(key, "") for key in ("log", "started_at", "finished_at")})
    return flat


def metric_columns(rows: Iterable[dict[str, Any]]) -> list[str]:
    """Every metric any row holds: the contract's keys first, then the others sorted."""
    extra = sorted({k for r in rows for k in r.get("metrics", {})}
                   - {*METRIC_KEYS, "outcome"})
    return [*METRIC_KEYS, *extra]


def write_tables(directory: SweepDir, spec: SweepSpec, rows: Sequence[dict[str, Any]],
                 n_runs: int) -> list[dict[str, Any]]:
    """``results.csv`` and ``results.json`` from the raw rows; returns the flat rows."""
    columns = metric_columns(rows)
    flat = [flat_row(r, spec, columns) for r in sorted(rows, key=lambda r: r["run_id"])]
    header = list(flat[0]) if flat else ["run_id", "point", "seed",
                                         *[p.path for p in spec.parameters], "pass"]
    with (directory.root / "results.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=header)
        writer.writeheader()
        writer.writerows({k: _csv_value(v) for k, v in r.items()} for r in flat)
    passed = sum(r["pass"] for r in flat)
    document = {
        "sweep": spec.name, "spec_hash": spec.digest(), "scenario": spec.scenario,
        "parameters": [{"path": p.path, "unit": p.unit, "nominal": p.nominal}
                       for p in spec.parameters],
        "criteria": [c.describe() for c in spec.criteria], "metric": spec.metric,
        "runs": n_runs, "finished": len(flat), "passed": passed, "rows": flat,
    }
    (directory.root / "results.json").write_text(
        json.dumps(document, indent=1, allow_nan=False) + "\n")
    return flat


def _finite_or_none(value: Any) -> Any:
    """JSON has no NaN: a non-finite metric is ``None`` (empty in the CSV)."""
    return None if isinstance(value, float) and not math.isfinite(value) else value


def _csv_value(value: Any) -> Any:
    if isinstance(value, bool):
        return "true" if value else "false"
    return "" if value is None else value


def as_number(value: Any) -> float:
    """A metric as a float; missing or non-numeric values are NaN."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return math.nan
    return float(value)


def bounds(spec: SweepSpec, metric: str) -> tuple[float | None, float | None]:
    """The pass criterion's (lower, upper) bound on ``metric`` (None where it has none)."""
    for criterion in spec.criteria:
        if criterion.metric == metric and not isinstance(criterion.bound, bool):
            upper = float(criterion.bound)
            lower = criterion.lower
            return (lower if lower is not None and math.isfinite(lower) else None,
                    upper if math.isfinite(upper) else None)
    return None, None


def low_is_bad(spec: SweepSpec, metric: str) -> bool:
    """Whether a smaller value of ``metric`` is the worse one: a criterion with only a
    lower bound (``gap_min_m: {min: 5}``), or a minimum over the run (``*_min_*``)."""
    lower, upper = bounds(spec, metric)
    if lower is not None or upper is not None:
        return lower is not None and upper is None
    return "_min_" in f"{metric}_" and not metric.endswith("_max")


def worst(values: Iterable[float], low_is_bad: bool = False) -> float:
    """The worst value: the largest, or the smallest where ``low_is_bad``
    (:func:`low_is_bad`); NaN if any is NaN (an errored run is the worst case)."""
    values = list(values)
    if not values or any(math.isnan(v) for v in values):
        return math.nan
    return min(values) if low_is_bad else max(values)


@dataclass(frozen=True)
class GridCells:
    """A two-parameter grid reduced over seeds: ``value[j][i]`` is the worst metric at
    ``(x_values[i], y_values[j])`` over the runs that went to their end; ``passed`` true if
    every seed passed; ``errors`` the number of runs that ended in an error; ``runs`` the runs
    finished in the cell; ``stopped`` how its runs that stopped early stopped (``""``: none
    did), a failure whatever ``value`` says (:func:`stopped_text`)."""

    x: Parameter
    y: Parameter
    value: list[list[float]]
    passed: list[list[bool]]
    errors: list[list[int]]
    runs: list[list[int]]
    stopped: list[list[str]]


def grid_cells(spec: SweepSpec, flat: Sequence[dict[str, Any]]) -> GridCells | None:
    """The heat map's cells, or ``None`` unless the sweep is a grid over two parameters."""
    if spec.mode != "grid" or len(spec.parameters) != 2:
        return None
    x, y = spec.parameters
    value, passed, errors, runs, stopped = [], [], [], [], []
    for yv in y.values:
        row_value, row_passed, row_errors, row_runs, row_stopped = [], [], [], [], []
        for xv in x.values:
            members = [r for r in flat if r[x.path] == xv and r[y.path] == yv]
            whole = [r for r in members if not r.get("partial")]
            row_value.append(worst((as_number(r[spec.metric]) for r in whole),
                                   low_is_bad(spec, spec.metric))
                             if whole else math.nan)
            row_passed.append(bool(members) and all(r["pass"] for r in members))
            row_errors.append(sum(bool(r["error"]) for r in members))
            row_runs.append(len(members))
            row_stopped.append(stopped_text(members))
        value.append(row_value)
        passed.append(row_passed)
        errors.append(row_errors)
        runs.append(row_runs)
        stopped.append(row_stopped)
    return GridCells(x, y, value, passed, errors, runs, stopped)


def stopped_text(members: Sequence[dict[str, Any]]) -> str:
    """How the runs among ``members`` that stopped early stopped: ``"spun at 3.07 s"`` for
    one, ``"spun: 2 of 5 runs"`` for several (the most frequent way first); ``""`` if
    none did."""
    stops = [r for r in members if r.get("partial")]
    if not stops:
        return ""
    if len(stops) == 1:
        return str(stops[0]["stopped"])
    kinds = collections.Counter(str(r["outcome"]).replace("_", " ") for r in stops)
    return ", ".join(kinds) + f": {len(stops)} of {len(members)} runs"


def _cell(value: Any) -> str:
    if isinstance(value, bool):
        return "pass" if value else "**FAIL**"
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else "n/a"
    if value is None:
        return "n/a"
    return str(value).replace("|", "\\|")


def _table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_cell(v) for v in row) + " |" for row in rows]
    return lines


def _groups(flat: Sequence[dict[str, Any]], spec: SweepSpec, index: int
            ) -> list[tuple[str, list[dict[str, Any]]]]:
    """Rows grouped by one parameter: by value (grid) or in equal-width bins (random)."""
    parameter = spec.parameters[index]
    if parameter.values:
        return [(_cell(v), [r for r in flat if r[parameter.path] == v])
                for v in parameter.values]
    low, high = float(parameter.low or 0.0), float(parameter.high or 0.0)
    width = (high - low) / RANDOM_BINS or 1.0
    groups = []
    for b in range(RANDOM_BINS):
        a, z = low + b * width, low + (b + 1) * width
        members = [r for r in flat if a <= r[parameter.path] < z
                   or (b == RANDOM_BINS - 1 and r[parameter.path] == z)]
        groups.append((f"[{a:.4g}, {z:.4g}{']' if b == RANDOM_BINS - 1 else ')'}", members))
    return groups


def summary_markdown(spec: SweepSpec, flat: Sequence[dict[str, Any]], n_runs: int,
                     plots: Sequence[Path], wall_time_s: float | None) -> str:
    """The Markdown summary of a sweep (``summary.md``)."""
    passed = sum(r["pass"] for r in flat)
    errors = sum(bool(r["error"]) for r in flat)
    lines = [f"# Sweep {spec.name}", ""]
    if spec.description:
        lines += [spec.description, ""]
    scenario = Path(spec.scenario).name if spec.scenario_text else spec.scenario
    lines += [
        f"- scenario `{scenario}`, tracker `{spec.tracker_name}`, "
        f"estimator `{spec.estimator_name}`"
        + (f", {spec.duration_s:g} s" if spec.duration_s is not None else ""),
        f"- seeds {', '.join(str(s) for s in spec.seeds)}; "
        + {"grid": "full factorial grid", "random": f"{spec.random_n} uniform samples "
           f"(sampling seed {spec.random_seed})", "seeds": "nothing varied but the seed"}
        [spec.mode] + f"; {n_runs} runs",
    ]
    if spec.fixed:
        lines.append("- fixed: " + ", ".join(f"`{k}={v}`" for k, v in spec.fixed))
    if wall_time_s is not None:
        lines.append(f"- wall time of this invocation {wall_time_s:.1f} s")
    lines.append("")
    if spec.parameters:
        lines += ["## What was varied", ""]
        lines += _table(
            ["parameter", "unit", "nominal", "values", "other side of the mismatch"],
            [[f"`{p.path}`", p.unit, _cell(p.nominal), p.describe_values(),
              f"`{p.counterpart}` = {_cell(p.counterpart_value)} (held)" if p.counterpart
              else ""] for p in spec.parameters])
        lines.append("")
    lines += ["## The belief against the plant", "",
              "Where the controller's model (and the filter's noise belief) differs from the "
              "plant before any varied value (`cosim.simulation.beliefs`): "
              + ("; ".join(spec.base_mismatch) if spec.base_mismatch else
                 "nowhere: every belief is the plant's value")
              + ". A varied key's other side is in the table above; each run's own table is "
              "in the `mismatch` column of `results.csv`.", ""]
    criteria = ", ".join(c.describe() for c in spec.criteria) or "the run completes"
    share = f"{100.0 * passed / len(flat):.1f} %" if flat else "n/a"
    lines += ["## Pass rate", "",
              f"**{passed} of {len(flat)} runs pass ({share})**; criteria: {criteria}."
              + (f" {errors} run(s) ended in an error." if errors else ""),
              ]
    if len(flat) < n_runs:
        lines.append(f"Only {len(flat)} of {n_runs} runs are finished: resume with "
                     "`--resume`.")
    lines.append("")
    outcomes = collections.Counter(r["outcome"] or "error" for r in flat)
    if outcomes:
        lines += ["## Outcomes", "", "How the runs ended (see `cosim.simulation.outcome`): "
                  + ", ".join(f"{kind} {count}" for kind, count in outcomes.most_common())
                  + ".", ""]

    lines += _worst_cases(spec, flat)
    lines += _grid_section(spec, flat)
    lines += _per_parameter(spec, flat)
    if plots:
        lines += ["## Plots", ""]
        lines += [f"![{p.stem}]({p.name})" for p in plots]
        lines.append("")
    return "\n".join(lines)


def _worst_cases(spec: SweepSpec, flat: Sequence[dict[str, Any]]) -> list[str]:
    """The summary's table of the worst runs by the headline metric."""
    metric, unit = spec.metric, unit_of(spec.metric)
    lines: list[str] = []
    sign = 1.0 if low_is_bad(spec, metric) else -1.0  # the worst first
    # Errors and runs that stopped early first: their metric is no measure of the run.
    key = [(-math.inf if r["error"] or r.get("partial") or math.isnan(as_number(r[metric]))
            else sign * as_number(r[metric])) for r in flat]
    order = sorted(range(len(flat)), key=lambda i: (key[i], flat[i]["run_id"]))
    lines += [f"## Worst cases by `{metric}`", ""]
    if any(r.get("partial") for r in flat):
        lines += ["A value marked *partial* is of a run that stopped early: it covers the run "
                  "up to the stop, and the run fails whatever it says.", ""]
    lines += _table(
        ["run", *[f"`{p.path}`" for p in spec.parameters], "seed", f"{metric} [{unit}]",
         "outcome", "result", "why"],
        [[flat[i]["run_id"], *[flat[i][p.path] for p in spec.parameters], flat[i]["seed"],
          _metric_cell(flat[i], metric), flat[i]["stopped"] or flat[i]["outcome"] or "-",
          flat[i]["pass"], flat[i]["failed"] or flat[i]["error"]]
         for i in order[:WORST_CASES]])
    lines.append("")

    return lines


def _metric_cell(row: dict[str, Any], metric: str) -> str | float:
    """A row's metric for a table: the number, marked *partial* where the run stopped
    early."""
    value = as_number(row[metric])
    if row.get("partial"):
        return f"{_cell(value)} *partial*"
    return value


def _grid_section(spec: SweepSpec, flat: Sequence[dict[str, Any]]) -> list[str]:
    """The summary's worst value per point of a two-parameter grid (none otherwise)."""
    metric = spec.metric
    lines: list[str] = []
    cells = grid_cells(spec, flat)
    if cells is not None:
        lines += [f"## Worst `{metric}` per grid point (over the seeds)", "",
                  f"Rows: `{cells.y.path}`; columns: `{cells.x.path}`; FAIL marks a point "
                  "where any seed fails; a point where a run stopped early (a spin ...) "
                  "says how instead of a value.", ""]
        header = [f"{axis_label(cells.y.path)} \\ {axis_label(cells.x.path)}",
                  *[_cell(v) for v in cells.x.values]]
        body = []
        for j, yv in enumerate(cells.y.values):
            body.append([yv, *[
                "not run" if not cells.runs[j][i] else "error" if cells.errors[j][i] else
                f"{cells.stopped[j][i]} FAIL" if cells.stopped[j][i] else
                f"{_cell(cells.value[j][i])}" + ("" if cells.passed[j][i] else " FAIL")
                for i in range(len(cells.x.values))]])
        lines += [*_table(header, body), ""]

    return lines


def _per_parameter(spec: SweepSpec, flat: Sequence[dict[str, Any]]) -> list[str]:
    """The summary's pass count, mean and worst value per value of each parameter."""
    metric, unit = spec.metric, unit_of(spec.metric)
    lines: list[str] = []
    if spec.parameters:
        lines += ["## Per parameter value", "",
                  f"Over every run with that value (all seeds, all other parameters); "
                  f"`{metric}` in {unit}.", ""]
        for index, parameter in enumerate(spec.parameters):
            lines += [f"### `{parameter.path}`", ""]
            rows = []
            for label, members in _groups(flat, spec, index):
                values = [as_number(r[metric]) for r in members]
                whole = [as_number(r[metric]) for r in members if not r.get("partial")]
                finite = [v for v in whole if not math.isnan(v)]
                good = sum(r["pass"] for r in members)
                errored = sum(bool(r["error"]) for r in members)
                stops = stopped_text(members)
                rows.append([label, len(members),
                             f"{good}/{len(members)}" if members else "-",
                             statistics.fmean(finite) if finite else math.nan,
                             f"error ({errored} run(s))" if errored else
                             f"stopped: {stops}" if stops else
                             worst(values, low_is_bad(spec, metric)) if members
                             else math.nan])
            lines += _table([axis_label(parameter.path), "runs", "pass",
                             f"mean {metric} (runs that went to their end)",
                             f"worst {metric}"], rows)
            lines.append("")
    return lines
