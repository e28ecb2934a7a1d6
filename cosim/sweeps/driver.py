"""``cosim sweep``: read the spec, run the missing runs on a backend, write the results.

:func:`run_sweep` is the whole command minus argument parsing:

1. :func:`cosim.sweeps.spec.load_spec` validates the spec (bad input raises before any run);
2. :meth:`cosim.sweeps.results.SweepDir.prepare` starts the output directory or, with
   ``resume``, checks that it holds a sweep of the same spec (same hash);
3. the runs whose ids are not yet in ``results.jsonl`` go to the backend; each finished row
   is appended to ``results.jsonl`` at once, so a kill loses only the runs in flight;
4. from every row: ``results.csv``, ``results.json``, ``summary.md`` and the plots.

An interrupt (Ctrl-C, SIGTERM) lets the running runs finish or stop, keeps every finished
row, writes the partial tables and re-raises ``KeyboardInterrupt`` for the CLI (exit 130).
"""

from __future__ import annotations

import contextlib
import datetime
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cosim.core.exceptions import CosimError
from cosim.sweeps.execute import make_backend
from cosim.sweeps.plots import heat_map, metric_plots
from cosim.sweeps.results import (
    SweepDir,
    append_row,
    failures,
    refuse_non_empty,
    summary_markdown,
    write_tables,
)
from cosim.sweeps.spec import SweepSpec, load_spec


@dataclass(frozen=True)
class SweepOutcome:
    """What a sweep invocation did and where its files are."""

    out_dir: Path
    runs: int
    """Runs in the spec."""
    finished: int
    """Runs with a row (this invocation's and earlier ones')."""
    ran: int
    """Runs this invocation finished."""
    passed: int
    errors: int
    files: tuple[Path, ...]
    wall_time_s: float


def default_out_dir(spec_path: Path) -> Path:
    """``logs/sweep-<spec stem>-<time>``."""
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path("logs") / f"sweep-{spec_path.stem}-{stamp}"


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM behaves like Ctrl-C while a sweep or a comparison runs (finish cleanly,
    keep the rows)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        del signum, frame
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class RunProgress:
    """Progress with ETA: a rich bar on a terminal, else one line per finished run
    (``cosim sweep``, ``cosim compare``)."""

    def __init__(self, total: int, done: int, label: str) -> None:
        self.total, self.done, self.label = total, done, label
        self.start = time.perf_counter()
        self.ran = 0
        self.bar: Any = None
        self.task: Any = None

    def __enter__(self) -> RunProgress:
        if sys.stderr.isatty():
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self.bar = Progress(TextColumn(self.label), BarColumn(),
                                MofNCompleteColumn(), TimeElapsedColumn(),
                                TextColumn("eta"), TimeRemainingColumn(),
                                console=Console(stderr=True), transient=True)
            self.bar.__enter__()
            self.task = self.bar.add_task("runs", total=self.total, completed=self.done)
        return self

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)

    def update(self, row: dict[str, Any], verdict: str) -> None:
        self.done += 1
        self.ran += 1
        if self.bar is not None:
            self.bar.update(self.task, completed=self.done)
            return
        elapsed = time.perf_counter() - self.start
        eta = elapsed / self.ran * (self.total - self.done)
        params = " ".join(f"{k}={v}" for k, v in row["params"].items())
        print(f"[{self.done}/{self.total}] run {row['run_id']} {params} seed {row['seed']}: "
              f"{verdict} (eta {eta:.0f} s)", file=sys.stderr, flush=True)


RUN_LIMIT = 10_000
"""A sweep of more runs than this is refused unless the user says ``--yes``."""


def check_size(spec: SweepSpec, spec_path: Path, yes: bool) -> None:
    """Refuse a sweep of more than :data:`RUN_LIMIT` runs unless ``yes``."""
    if spec.n_runs > RUN_LIMIT and not yes:
        raise CosimError(f"sweep spec {str(spec_path)!r}: {spec.n_runs:,} runs: expected at "
                         f"most {RUN_LIMIT:,} (or --yes to run them all)")


def check_sweep_dir(out: Path, force: bool = False, resume: bool = False) -> None:
    """Refuse a sweep --out that names a file, a folder with files in it (unless ``force``
    or ``resume``), or a place where no directory can be made (checked without making
    anything: a refused spec leaves no directory behind)."""
    if out.exists() and not out.is_dir():
        raise CosimError(f"--out {str(out)!r}: is a file: expected a directory for the sweep")
    if not (force or resume):
        refuse_non_empty(out, "start the sweep afresh there", "finish the sweep it holds")
    existing = next(p for p in (out, *out.parents) if p.exists() or p == Path(p.anchor))
    if not existing.is_dir():
        raise CosimError(f"--out {str(out)!r}: cannot make the directory ({str(existing)!r} "
                         "is a file): expected a writable place")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise CosimError(f"--out {str(out)!r}: cannot make the directory ({str(existing)!r} "
                         "is not writable): expected a writable place")


def run_sweep(spec_path: str | Path, out_dir: str | Path | None = None,
              workers: int | None = None, backend: str = "process",
              keep_logs: bool = False, resume: bool = False,
              on_row: Callable[[dict[str, Any]], None] | None = None,
              yes: bool = False, force: bool = False) -> SweepOutcome:
    """Run (or finish, with ``resume``) the sweep of ``spec_path`` into ``out_dir``.

    ``workers``: processes (``process``) or tasks in flight (``ray``); default: the cores
    this process may use (``process``), Ray's own scheduling (``ray``). ``force`` starts the
    sweep afresh in a folder that holds another (its rows are dropped). ``on_row`` is called
    with each raw row as it lands (tests use it). Raises :class:`cosim.core.exceptions.CosimError`
    on bad input (a sweep above :data:`RUN_LIMIT` runs without ``yes`` included),
    ``KeyboardInterrupt`` after an interrupt (rows kept, tables written, plots skipped so
    that the interrupt acts at once), ``OSError`` when a row cannot be written (a full
    disk: the rows written so far are kept, ``--resume`` runs the others).
    """
    start = time.perf_counter()
    spec_path = Path(spec_path)
    spec = load_spec(spec_path)
    check_size(spec, spec_path, yes)
    runner = make_backend(backend, workers, spec.ray_address)
    directory = SweepDir(Path(out_dir) if out_dir is not None else default_out_dir(spec_path))
    tasks = spec.tasks(directory.log_dir if keep_logs else None)
    directory.prepare(spec, spec_path.read_text(encoding="utf-8-sig"), resume, len(tasks),
                      force)
    rows = {run_id: row for run_id, row in directory.read_rows().items()
            if run_id < len(tasks)}
    missing = [task for task in tasks if task.run_id not in rows]
    ran = 0
    interrupted = False
    progress_bar = RunProgress(len(tasks), len(rows), f"sweep {spec.name}")
    with directory.open_rows() as handle, progress_bar as progress:

        def land(row: dict[str, Any]) -> None:
            nonlocal ran
            if row.get("interrupted"):
                return  # not a result: --resume runs it again
            append_row(handle, row)
            rows[row["run_id"]] = row
            ran += 1
            why = failures(row, spec)  # a collision, a spin: named first
            progress.update(row, "pass" if not why else "FAIL " + why[0])
            if on_row is not None:
                on_row(row)

        try:
            with sigterm_as_interrupt():
                runner.run(missing, land)
        except KeyboardInterrupt:
            interrupted = True
    files = _write_outputs(directory, spec, list(rows.values()), len(tasks),
                           time.perf_counter() - start, plots=not interrupted)
    if interrupted:
        raise KeyboardInterrupt
    flat_pass = [not failures(r, spec) for r in rows.values()]
    return SweepOutcome(
        out_dir=directory.root, runs=len(tasks), finished=len(rows), ran=ran,
        passed=sum(flat_pass), errors=sum(bool(r.get("error")) for r in rows.values()),
        files=files, wall_time_s=time.perf_counter() - start)


def _write_outputs(directory: SweepDir, spec: SweepSpec, rows: list[dict[str, Any]],
                   n_runs: int, wall_time_s: float, plots: bool = True) -> tuple[Path, ...]:
    """The tables, the summary and (unless ``plots`` is false) the figures."""
    flat = write_tables(directory, spec, rows, n_runs)
    figures: list[Path] = []
    if flat and plots:
        heat = heat_map(spec, flat, directory.root / f"heatmap-{spec.metric}.png")
        figures = [heat] if heat is not None else []
        figures += metric_plots(spec, flat, directory.root)
    summary = directory.root / "summary.md"
    summary.write_text(summary_markdown(spec, flat, n_runs, figures, wall_time_s))
    return (directory.root / "results.csv", directory.root / "results.json", summary,
            *figures)
