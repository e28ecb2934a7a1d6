"""`cosim plot`: PNG figures of one run, or of several runs overlaid (up to
:data:`MAX_LOGS`).

``data`` reads a log into typed arrays; one module per figure group:

=====================  ==========================================================
``top_view.png``       path vs reference: true scale with footprints, the manoeuvre
                       stretched laterally, deviation in path coordinates, zooms;
                       the MPC's predicted paths (``top_view``)
``tracking.png``       CTE, heading error, speed vs reference over time (``tracking``)
``commands.png``       steering, steering rate, acceleration with the tracker's limits
                       (``commands``)
``estimation.png``     the vehicle's states: estimate - truth with +-3 sigma, NEES,
                       NIS per sensor (``estimation``)
``estimation_internal.png``  the filter's biases, scales and residuals, truth where
                       logged (``estimation``)
``solver.png``         solve-time histogram with p50/p99, over time, fallbacks
                       (``solver``)
``acc.png``            logs with traffic only: gap with the desired and minimum safe
                       gaps, speeds, ACC mode and acceleration, ESC's gains (``acc``)
=====================  ==========================================================

matplotlib is used through ``Figure`` objects on their own Agg canvas (no pyplot state).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from pathlib import Path

from cosim.core.exceptions import CosimError

MAX_LOGS = 6
"""Logs one figure overlays: more lines than this no eye tells apart."""

FIGURES = ("top_view", "tracking", "commands", "estimation", "solver")
"""The PNG files written, in this order (``<name>.png``)."""


def default_out_dir(paths: Sequence[Path]) -> Path:
    """Beside the first log: ``<stem>-plots``, ``<stem>-vs-<stem2>-plots``, or for more
    logs ``<stem>-vs-<n>-more-plots``."""
    stem = "-vs-".join(p.stem for p in paths) if len(paths) <= 2 else \
        f"{paths[0].stem}-vs-{len(paths) - 1}-more"
    return paths[0].parent / f"{stem}-plots"


def plot_logs(paths: Sequence[Path | str], out_dir: Path | str | None = None,
              labels: Sequence[str] = (), processes: int | None = None) -> list[Path]:
    """Write every figure of one log, or of several logs overlaid; returns the PNG paths.
    ``labels``, if given, name the logs in the legends, one a log in order (else each is
    named by what differs in its configuration). ``processes``: how many processes draw
    the figures (:func:`cosim.plots.drawing.draw`; None: two where there are two cores)."""
    from cosim.plots.acc import acc_figure, load_acc
    from cosim.plots.commands import commands_figure
    from cosim.plots.data import distinct_labels, load_run
    from cosim.plots.drawing import FigureJob, draw
    from cosim.plots.estimation import estimation_figure, estimation_internal_figure
    from cosim.plots.solver import solver_figure
    from cosim.plots.top_view import top_view_figure
    from cosim.plots.tracking import tracking_figure

    paths = [Path(p) for p in paths]
    if not 1 <= len(paths) <= MAX_LOGS:
        raise CosimError(f"{len(paths)} logs: expected one log, or up to {MAX_LOGS} to "
                         "overlay")
    if labels and len(labels) != len(paths):
        raise CosimError(f"--label given {len(labels)} time(s) for {len(paths)} log(s): "
                         "expected one --label per log, in the order of the logs")
    if labels and len(set(labels)) != len(labels):
        raise CosimError(f"--label {', '.join(repr(x) for x in labels)}: expected a different "
                         "label for each log")
    runs = [load_run(p) for p in paths]
    if labels:
        from dataclasses import replace

        runs = [replace(run, label=label) for run, label in zip(runs, labels, strict=True)]
    else:
        runs = distinct_labels(runs)
    out = Path(out_dir) if out_dir is not None else default_out_dir(paths)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise CosimError(f"--out {str(out)!r}: cannot create the directory "
                         f"({error.strerror})") from None
    makers: dict[str, Callable] = {
        "top_view": top_view_figure, "tracking": tracking_figure,
        "commands": commands_figure, "estimation": estimation_figure,
        "solver": solver_figure,
    }
    jobs: list[FigureJob] = [functools.partial(makers[name], runs, out / f"{name}.png")
                             for name in FIGURES]
    jobs.insert(FIGURES.index("estimation") + 1, functools.partial(
        estimation_internal_figure, runs, out / "estimation_internal.png"))
    # A log whose configuration has no traffic has no ACC topics: not read a second time
    # for them (a log without its configuration, an old one, is).
    acc_logs = [None if run.config and not run.config.get("traffic") else load_acc(run.path)
                for run in runs]
    if any(log is not None for log in acc_logs):  # runs with traffic
        with_traffic = [(r, log) for r, log in zip(runs, acc_logs, strict=True)
                        if log is not None]
        jobs.append(functools.partial(acc_figure, [r for r, _ in with_traffic],
                                      [log for _, log in with_traffic], out / "acc.png"))
    return [path for path in draw(jobs, processes) if path is not None]


def plot_command(files: Sequence[str], out_dir: str | None, labels: Sequence[str] = ()) -> int:
    """`cosim plot FILE [FILE ...] [--out DIR] [--label L ...]`: write the PNGs and print
    their paths."""
    for written in plot_logs(list(files), out_dir, labels):
        print(written)
    return 0
