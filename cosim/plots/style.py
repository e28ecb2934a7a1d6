"""What every figure of `cosim plot` shares: the canvas, colours, titles and notes.

Figures are ``matplotlib.figure.Figure`` objects on their own Agg canvas: no pyplot, no
global state, no display needed.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from cosim.plots.data import RunLog
from cosim.simulation.beliefs import mismatch_short
from cosim.simulation.changes import changes_text

DPI = 130
RUN_COLOURS = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive")
"""Run A, run B, ... (green is the estimate's, grey the reference's)."""
REFERENCE_COLOUR = "0.25"
ESTIMATE_COLOUR = "tab:green"
LIMIT_COLOUR = "tab:red"
FONT_SIZE = 9


def new_figure(width_in: float, height_in: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width_in, height_in), dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def style_axes(ax: Any) -> None:
    ax.grid(True, alpha=0.35, linewidth=0.6)
    ax.tick_params(labelsize=FONT_SIZE)
    ax.xaxis.label.set_size(FONT_SIZE + 1)
    ax.yaxis.label.set_size(FONT_SIZE + 1)


RUN_LINESTYLES: tuple[Any, ...] = ("-", (0, (7.0, 2.0, 1.5, 2.0)))
"""Run A solid, run B dash-dot: two nearly equal runs stay apart even where they overlap
(and in grey print)."""


def run_colour(index: int) -> str:
    return RUN_COLOURS[index % len(RUN_COLOURS)]


def run_line(index: int) -> dict[str, Any]:
    """Colour and line style of run ``index``'s main lines (``ax.plot(..., **run_line(i))``)."""
    return {"color": run_colour(index),
            "linestyle": RUN_LINESTYLES[index % len(RUN_LINESTYLES)]}


def suptitle(figure: Any, what: str, runs: Sequence[RunLog]) -> None:
    """``what``, then the runs: label, seed, what a single run changed from its scenario,
    and TRUNCATED / not completed marks."""
    parts = []
    for run in runs:
        marks = []
        if run.truncated:
            marks.append("TRUNCATED log")
        if run.metrics is not None and run.metrics.get("completed") is False:
            marks.append(f"aborted: {run.metrics.get('abort_reason', '?')}")
        seed = run.config.get("seed")
        text = run.label + (f", seed {seed}" if seed is not None else "")
        if len(runs) == 1 and run.changes:  # runs of several logs name their differences
            text += f" — {changes_text(run.changes)}"
        if len(runs) == 1 and mismatch_short(run.config):  # the truth beside the belief
            text += f"\n{mismatch_short(run.config)}"
        parts.append(text + (f" ({'; '.join(marks)})" if marks else ""))
    common = [c for c in runs[0].changes if all(c in run.changes for run in runs[1:])] \
        if len(runs) > 1 else []
    shared = f"\nall runs: {changes_text(common)}" if common else ""
    # As many characters a line as the figure is wide (about 9 per inch at this size).
    columns = max(40, int(figure.get_figwidth() * 9)) if hasattr(figure, "get_figwidth") \
        else 10_000
    runs_text = "\n".join(textwrap.fill(line, columns, break_long_words=False)
                          for line in "  vs  ".join(parts).split("\n"))
    figure.suptitle(f"{what}\n{runs_text}{shared}", fontsize=FONT_SIZE + 3)


def note(ax: Any, text: str, loc: str = "lower right") -> None:
    """A boxed remark inside the axes (what is missing, and why)."""
    from matplotlib.offsetbox import AnchoredText

    box = AnchoredText(text, loc=loc, prop={"size": FONT_SIZE - 0.5}, frameon=True)
    box.patch.set_alpha(0.85)
    box.patch.set_edgecolor("0.6")
    ax.add_artist(box)


_GENERIC = "\x00"
"""Marks a legend label that names a line style rather than a run (see :func:`generic`)."""


def generic(index: int, text: str) -> str | None:
    """A legend label for what a line style means (not which run): given by the first run
    only, and drawn grey by :func:`legend` when runs are overlaid (colour = run)."""
    return _GENERIC + text if index == 0 else None


def legend(ax: Any, runs: Sequence[RunLog], **kwargs: Any) -> None:
    """The axes' legend, outside the axes on the right (never over the data) unless
    ``loc``/``bbox_to_anchor`` say otherwise; with two runs, style-only entries are grey."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    kwargs.setdefault("loc", "upper left")
    kwargs.setdefault("bbox_to_anchor", (1.01, 1.0))
    kwargs.setdefault("borderaxespad", 0.0)
    kwargs.setdefault("fontsize", FONT_SIZE - 1)
    shown = ax.legend(handles, [label.removeprefix(_GENERIC) for label in labels],
                      framealpha=0.85, **kwargs)
    if len(runs) < 2:
        return
    for handle, label in zip(shown.legend_handles, labels, strict=True):
        if not label.startswith(_GENERIC) or handle is None:
            continue
        if hasattr(handle, "set_facecolor"):
            handle.set_facecolor("0.75")
            handle.set_edgecolor("0.4")
        else:
            handle.set_color("0.35")


def run_legend(figure: Any, runs: Sequence[RunLog]) -> None:
    """With two runs: one figure legend saying which colour is which run."""
    if len(runs) < 2:
        return
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], linewidth=2.5, label=run.label, **run_line(i))
               for i, run in enumerate(runs)]
    figure.legend(handles=handles, loc="outside lower center",
                  ncol=legend_columns([run.label for run in runs], figure, FONT_SIZE + 1),
                  fontsize=FONT_SIZE + 1, frameon=False)


def legend_columns(labels: Sequence[str], figure: Any, font_size_pt: float) -> int:
    """Columns of a figure legend that fit its width: as many entries side by side as the
    longest label allows (a character is about 0.6 em wide; a handle and the gap about
    4 em), down to one entry a row."""
    width_pt = figure.get_figwidth() * 72.0
    entry_pt = (0.6 * max(map(len, labels), default=1) + 4.0) * font_size_pt
    return max(1, min(len(labels), int(width_pt // entry_pt)))


def save(figure: Any, path: Path) -> Path:
    """``figure`` (made by :func:`new_figure`) as a PNG at :data:`DPI`, drawn once.

    ``savefig`` of a figure with a layout engine draws it whole without rendering, only to
    lay it out, then again to render it with the layout turned off. Here the constrained
    layout is laid out first (the same engine on the same figure at the same DPI, so the
    same positions) and fixed, and the canvas renders the figure in one draw: the same
    bytes as ``savefig`` writes, about a sixth less time per figure."""
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    engine = figure.get_layout_engine()
    if not isinstance(engine, ConstrainedLayoutEngine) or figure.dpi != DPI:
        figure.savefig(path, dpi=DPI)
        return path
    engine.execute(figure)
    figure.set_layout_engine("none")
    figure.canvas.print_png(path)
    return path


def time_axis(ax: Any) -> None:
    ax.set_xlabel("simulated time t [s]")


def finish(figure: Any, axes: Sequence[Any], runs: Sequence[RunLog], what: str,
           path: Path) -> Path:
    """Style and label every panel, title the figure, add the run legend, save it."""
    for ax in axes:
        style_axes(ax)
        legend(ax, runs)
    suptitle(figure, what, runs)
    run_legend(figure, runs)
    return save(figure, path)
