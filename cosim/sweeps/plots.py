"""Plots of a sweep (PNG, matplotlib's Agg backend: no display needed).

* A **heat map** when the sweep is a grid over exactly two parameters: one cell per point,
  its colour and number the worst (largest) value of the headline metric over the seeds.
  With an upper-bound pass criterion on that metric, the colour scale is centred on the
  bound (green below, red above, logarithmic, because a failed lane change is metres where a
  good one is centimetres), failing cells say FAIL, and cells whose run errored are grey.
  A cell where a run stopped early (a spin, a rollover ...) is hatched and says how, with
  no value: the metric of a stopped run covers the run up to the stop, so a colour would
  show a partial measurement as a whole one.
  Axes carry the dotted keys with units; the nominal value is marked on each axis.
* A **metric-vs-parameter** plot for each varied parameter: every run as a point (pass and
  fail drawn differently), the worst over seeds per grid value as a line, the bound dashed.

matplotlib is imported inside the functions, with the Agg backend chosen on the figure's
own canvas, so importing this module changes no global state.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from cosim.sweeps.results import as_number, bounds, grid_cells, low_is_bad
from cosim.sweeps.spec import Parameter, SweepSpec, axis_label, unit_of

DPI = 130


def _figure(width_in: float, height_in: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width_in, height_in), dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def _bound(spec: SweepSpec) -> float | None:
    lower, upper = bounds(spec, spec.metric)
    return upper if upper is not None else lower


def _tick_labels(parameter: Parameter) -> list[str]:
    labels = []
    for value in parameter.values:
        text = f"{value:g}" if isinstance(value, float) else str(value)
        labels.append(text + ("\n(nominal)" if value == parameter.nominal else ""))
    return labels


def _title(spec: SweepSpec) -> str:
    """The sweep's name, then the scenario unless the sweep is named after it, then the
    tracker and the estimator."""
    scenario = Path(spec.scenario).stem if spec.scenario_text else spec.scenario
    head = spec.name if spec.name == scenario else f"{spec.name}: {scenario}"
    return f"{head}, {spec.tracker_name} + {spec.estimator_name}"


def _belief_note(spec: SweepSpec) -> str:
    """The other side of each varied plant/belief pair, which the sweep holds fixed."""
    held = []
    for p in spec.parameters:
        if p.counterpart:
            value = p.counterpart_value
            text = f"{value:g}" if isinstance(value, float) else str(value)
            unit = unit_of(p.counterpart)
            held.append(f"{p.counterpart} = {text}" + (f" {unit}" if unit != "-" else ""))
    return ("held fixed (the other side of the mismatch): " + ", ".join(held)) if held else ""


def heat_map(spec: SweepSpec, flat: Sequence[dict[str, Any]], path: Path) -> Path | None:
    """Write the two-parameter heat map to ``path`` (``None`` if the sweep has no grid of
    two parameters)."""
    cells = grid_cells(spec, flat)
    if cells is None:
        return None
    import numpy as np
    from matplotlib import colors

    metric, unit = spec.metric, unit_of(spec.metric)
    bound = _bound(spec)
    data = np.array(cells.value, dtype=float)
    data[np.array(cells.stopped, dtype=bool)] = np.nan  # failures, drawn as such
    finite = data[np.isfinite(data)]
    width_in = max(5.0, 1.6 + 1.25 * len(cells.x.values))
    figure = _figure(width_in, 1.9 + 0.8 * len(cells.y.values))
    axes = figure.add_subplot()
    positive = finite[finite > 0]
    if bound is not None and bound > 0 and positive.size == finite.size:
        # Log scale centred on the bound: green passes, red fails, whatever the spread.
        low = min(float(positive.min()) if positive.size else bound, bound / 3.0)
        high = max(float(positive.max()) if positive.size else bound, bound * 3.0)
        norm = colors.TwoSlopeNorm(vmin=math.log10(low), vcenter=math.log10(bound),
                                   vmax=math.log10(high))
        shown = np.log10(np.where(data > 0, data, np.nan))
        cmap = "RdYlGn_r"
        log_scale = True
    else:
        norm = None
        shown = data
        cmap = "viridis"
        log_scale = False
    cmap_obj = _colormap(cmap)
    image = axes.imshow(np.ma.masked_invalid(shown), cmap=cmap_obj, norm=norm, origin="lower",
                        aspect="auto")
    bar = figure.colorbar(image, ax=axes, shrink=0.9)
    seeds = len(spec.seeds)
    bar.set_label(f"worst {metric} over {seeds} seed{'s' if seeds > 1 else ''} [{unit}]",
                  fontsize=9)
    if log_scale:
        ticks = _log_ticks(norm.vmin, norm.vmax, bound)
        bar.set_ticks([math.log10(t) for t in ticks])
        bar.set_ticklabels([f"{t:g}" for t in ticks])
        bar.ax.axhline(math.log10(bound), color="black", linewidth=1.5)
    for j in range(len(cells.y.values)):
        for i in range(len(cells.x.values)):
            value = cells.value[j][i]
            if cells.runs[j][i] == 0:
                text, weight = "not run", "normal"
            elif cells.stopped[j][i]:  # a failure, not a value: no colour of the scale
                text = "\n".join(textwrap.wrap(cells.stopped[j][i], 14)) + "\nFAIL"
                weight = "bold"
                axes.add_patch(_stopped_cell(i, j))
            elif cells.errors[j][i] and not math.isfinite(value):
                text = f"error\n({cells.errors[j][i]} of {cells.runs[j][i]} runs)"
                weight = "bold"
            else:
                verdict = "pass" if cells.passed[j][i] else "FAIL"
                text, weight = f"{value:.3g}\n{verdict}", ("normal" if cells.passed[j][i]
                                                            else "bold")
            colour = "black"
            if math.isfinite(shown[j, i]) and not cells.stopped[j][i]:
                rgba = cmap_obj(norm(shown[j, i]) if norm is not None else
                                (shown[j, i] - finite.min()) / (np.ptp(finite) or 1.0))
                colour = "white" if 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2] < 0.5 \
                    else "black"
            axes.text(i, j, text, ha="center", va="center", fontsize=9, color=colour,
                      fontweight=weight)
            if not cells.passed[j][i] and cells.runs[j][i]:
                axes.add_patch(_cell_frame(i, j))
    axes.set_facecolor("0.8")  # cells with no value (errors) show grey
    axes.set_xticks(range(len(cells.x.values)), _tick_labels(cells.x))
    axes.set_yticks(range(len(cells.y.values)), _tick_labels(cells.y))
    axes.set_xlabel(axis_label(cells.x.path))
    axes.set_ylabel(axis_label(cells.y.path))
    criteria = ", ".join(c.describe() for c in spec.criteria) or "run completes"
    axes.set_title(f"{_title(spec)}\npass: {criteria}", fontsize=10)
    note = _belief_note(spec)
    if note:
        figure.supxlabel(textwrap.fill(note, width=int(width_in * 15)), fontsize=8,
                         color="0.3")
    figure.savefig(path)
    return path


def _colormap(name: str) -> Any:
    from matplotlib import colormaps

    return colormaps[name]


def _stopped_cell(i: int, j: int) -> Any:
    """A cell whose runs stopped early (a spin ...): hatched, outside the colour scale."""
    from matplotlib.patches import Rectangle

    return Rectangle((i - 0.5, j - 0.5), 1.0, 1.0, facecolor="0.55", edgecolor="black",
                     hatch="//", linewidth=0.0, zorder=1.5)


def _cell_frame(i: int, j: int) -> Any:
    from matplotlib.patches import Rectangle

    return Rectangle((i - 0.5, j - 0.5), 1.0, 1.0, fill=False, edgecolor="black",
                     linewidth=2.0)


def _log_ticks(log_low: float, log_high: float, bound: float) -> list[float]:
    """Round colour-bar ticks (1, 2, 5 per decade) in the range, plus the bound."""
    ticks = {bound}
    for exponent in range(math.floor(log_low) - 1, math.ceil(log_high) + 1):
        for mantissa in (1.0, 2.0, 5.0):
            tick = mantissa * 10.0**exponent
            if log_low <= math.log10(tick) <= log_high:
                ticks.add(tick)
    ordered = sorted(ticks)
    # Drop ticks crowding the bound (within 15 % of a decade) so its label stays legible.
    return [t for t in ordered if t == bound or abs(math.log10(t / bound)) > 0.15]


def metric_plots(spec: SweepSpec, flat: Sequence[dict[str, Any]], directory: Path
                 ) -> list[Path]:
    """One ``<metric>-vs-<parameter>.png`` per plotted metric and varied parameter."""
    paths = []
    for metric in spec.metrics:
        for parameter in spec.parameters:
            path = directory / f"{metric}-vs-{parameter.path}.png"
            _metric_plot(spec, flat, parameter, path, metric)
            paths.append(path)
    return paths


EVENT_MARKERS = {"collision": "X", "spun": "v", "rolled_over": "s", "off_road": "D",
                 "end_of_path": ">"}
"""How a run that ended in an event is drawn (its outcome names it in the legend)."""


def _shade_events(axes: Any, flat: Sequence[dict[str, Any]], parameter: Parameter,
                  events: Sequence[str], ended_in_event: Any) -> None:
    """Shade the parameter values where some run ended in an event, each from half-way to
    its neighbours: only those values, so a value where every run passed is never shaded."""
    values = sorted(float(v) for v in parameter.values)
    hit = {float(v) for v in parameter.values
           if any(ended_in_event(r) for r in flat if r[parameter.path] == v)}
    kinds = " / ".join(k.replace("_", " ") for k in events)
    labelled = False
    for k, value in enumerate(values):
        if value not in hit:
            continue
        half_left = 0.5 * (value - values[k - 1]) if k > 0 else None
        half_right = 0.5 * (values[k + 1] - value) if k + 1 < len(values) else None
        half = (half_left or half_right or 0.02 * (abs(value) or 1.0))  # ends mirror
        left = value - (half_left if half_left is not None else half)
        right = value + (half_right if half_right is not None else half)
        axes.axvspan(left, right, color="tab:red", alpha=0.08,
                     label=None if labelled else f"values with an event ({kinds})")
        labelled = True


def _metric_plot(spec: SweepSpec, flat: Sequence[dict[str, Any]], parameter: Parameter,
                 path: Path, metric: str | None = None) -> None:
    metric = metric or spec.metric
    unit = unit_of(metric)
    lower, upper = bounds(spec, metric)
    smaller_is_worse = low_is_bad(spec, metric)
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool)
                  for v in (parameter.values or (0.0,)))

    def position(value: Any) -> float:
        return float(value) if numeric else float(parameter.values.index(value))

    def ended_in_event(row: dict[str, Any]) -> bool:
        return not row["error"] and row.get("outcome") in EVENT_MARKERS

    figure = _figure(6.4, 4.2)
    axes = figure.add_subplot()
    good = [(position(r[parameter.path]), as_number(r[metric])) for r in flat if r["pass"]]
    bad = [(position(r[parameter.path]), as_number(r[metric])) for r in flat
           if not r["pass"] and not r["error"] and not ended_in_event(r)]
    errored = sum(bool(r["error"]) for r in flat)
    if good:
        axes.plot(*zip(*good, strict=True), "o", color="tab:green", alpha=0.7,
                  label="run: pass")
    if bad:
        axes.plot(*zip(*bad, strict=True), "x", color="tab:red", markersize=8,
                  label="run: fail")
    events = sorted({str(r["outcome"]) for r in flat if ended_in_event(r)})
    edge = 0.04 if smaller_is_worse else 0.96  # a stopped run sits at the bad edge
    for kind in events:
        ended = [r for r in flat if ended_in_event(r) and r["outcome"] == kind]
        whole = [(position(r[parameter.path]), as_number(r[metric])) for r in ended
                 if not r.get("partial")]
        stopped = [position(r[parameter.path]) for r in ended if r.get("partial")]
        name = kind.replace("_", " ")
        if whole:
            axes.plot(*zip(*whole, strict=True), EVENT_MARKERS[kind], color="black",
                      markersize=8, label=f"run: {name} (fails)")
        if stopped:  # a failure, not a value: its metric covers the run up to the stop
            axes.plot(stopped, [edge] * len(stopped), EVENT_MARKERS[kind], color="tab:red",
                      markersize=9, clip_on=False, transform=axes.get_xaxis_transform(),
                      label=f"run: {name}, stopped (fails; no value)")
    if events and numeric and parameter.values:
        _shade_events(axes, flat, parameter, events, ended_in_event)
    if parameter.values:
        xs, ys = [], []
        for value in parameter.values:
            members = [as_number(r[metric]) for r in flat if r[parameter.path] == value
                       and not r["error"] and not r.get("partial")]
            if members:
                xs.append(position(value))
                ys.append(min(members) if smaller_is_worse else max(members))
        axes.plot(xs, ys, "-", color="0.3", linewidth=1.0, label="worst per value")
        if not numeric:
            axes.set_xticks(range(len(parameter.values)), [str(v) for v in parameter.values])
    for bound, name in ((upper, "bound"), (lower, "lower bound")):
        if bound is not None:
            axes.axhline(bound, color="black", linestyle="--", linewidth=1.0,
                         label=f"{name} {bound:g} {unit}")
    if isinstance(parameter.nominal, (int, float)) and numeric:
        axes.axvline(float(parameter.nominal), color="tab:blue", linestyle=":",
                     linewidth=1.0, label=f"nominal {parameter.nominal:g}")
    values = [v for _, v in good + bad if math.isfinite(v) and v > 0]
    if values and max(values) / min(values) > 30.0 and not events:
        axes.set_yscale("log")
    axes.set_xlabel(axis_label(parameter.path))
    axes.set_ylabel(f"{metric} [{unit}]")
    others = [p.path for p in spec.parameters if p is not parameter]
    over = "seeds" + (" and " + ", ".join(others) if others else "")
    suffix = f"; {errored} run(s) ended in an error (not shown)" if errored else ""
    line = f", line: worst over {over}" if parameter.values else ""
    axes.set_title(f"{_title(spec)}\none point per run{line}{suffix}", fontsize=10)
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=8)
    figure.savefig(path)
