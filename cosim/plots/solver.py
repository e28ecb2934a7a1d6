"""The tracker's solve time per control step: histogram with p50/p99, and over time.

Times come from each plan's ``solve_time_s`` (the tracker's wall time per step, as the
metrics' ``solve_ms_*``); steps that used a fallback are counted in the title and marked on
the time plot. The bins are logarithmic when the runs' times span more than a decade (an
NMPC next to a QP-based MPC).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cosim.plots.data import RunLog
from cosim.plots.style import (
    LIMIT_COLOUR,
    generic,
    legend,
    new_figure,
    note,
    run_colour,
    run_legend,
    run_line,
    save,
    style_axes,
    suptitle,
    time_axis,
)


def solver_figure(runs: Sequence[RunLog], path: Path) -> Path:
    figure = new_figure(11.0, 8.0)
    hist_ax, time_ax = figure.subplots(2, 1, height_ratios=[3, 2])
    times_ms = [run.plans.solve_time_s * 1e3 if run.plans is not None else np.empty(0)
                for run in runs]
    finite = np.concatenate([t[np.isfinite(t) & (t > 0)] for t in times_ms])
    log_bins = finite.size > 0 and finite.max() / finite.min() > 10.0
    if finite.size == 0:
        bins = np.linspace(0.0, 1.0, 2)
    elif log_bins:
        bins = np.geomspace(finite.min() * 0.9, finite.max() * 1.1, 60)
    else:
        span = finite.max() - finite.min()
        bins = np.linspace(max(0.0, finite.min() - 0.1 * span), finite.max() + 0.1 * span, 60)
    title_parts = []
    for i, (run, solve_ms) in enumerate(zip(runs, times_ms, strict=True)):
        colour = run_colour(i)
        plans = run.plans
        if plans is None or solve_ms.size == 0:
            note(hist_ax, f"{run.label}: no /control/plan messages")
            continue
        p50, p99 = np.nanpercentile(solve_ms, [50.0, 99.0])
        fallbacks = int(np.sum(plans.fallback))
        title_parts.append((f"{run.tracker_name}: " if len(runs) == 1 else "")
                           + f"{fallbacks} fallback{'' if fallbacks == 1 else 's'} in "
                             f"{solve_ms.size} steps")
        hist_ax.hist(solve_ms, bins=bins, color=colour, alpha=0.55,
                     label=f"{solve_ms.size} steps")
        for value, name, style in ((p50, "p50", "--"), (p99, "p99", ":")):
            hist_ax.axvline(value, color=colour, linestyle=style, linewidth=1.6,
                            label=f"{name} {value:.3g} ms")
            if len(runs) > 1:
                continue  # two runs' labels would overlap: the legend has the values
            hist_ax.annotate(f"{name} {value:.3g} ms", xy=(value, 0.5),
                             xycoords=("data", "axes fraction"), xytext=(-3, 0),
                             textcoords="offset points", ha="right", va="center",
                             rotation=90, fontsize=8, color=colour)
        time_ax.plot(plans.t_s, solve_ms, linewidth=0.9, **run_line(i), marker=".",
                     markersize=2.5, label=generic(i, "solve time per control step"))
        if fallbacks:
            statuses = Counter(np.asarray(plans.status)[plans.fallback].tolist())
            counted = "; ".join(f"{n} x {status}" for status, n in statuses.most_common(3))
            time_ax.plot(plans.t_s[plans.fallback], solve_ms[plans.fallback], linestyle="none",
                         marker="x", color=LIMIT_COLOUR if i == 0 else "tab:purple",
                         markersize=5, label=f"fallback steps: {counted}")
    control_periods = {run.config.get("sim", {}).get("control_period_s") for run in runs}
    control_periods.discard(None)
    for period in control_periods:
        budget = f"control period {period * 1e3:g} ms (real-time budget)"
        if finite.size and period * 1e3 < 3.0 * finite.max():
            time_ax.axhline(period * 1e3, color=LIMIT_COLOUR, linestyle="--", linewidth=1.0,
                            label=budget)
        else:
            time_ax.plot([], [], color=LIMIT_COLOUR, linestyle="--", linewidth=1.0,
                         label=f"{budget}: off scale")
    if log_bins:
        hist_ax.set_xscale("log")
        time_ax.set_yscale("log")
    hist_ax.set_xlabel("solve time per control step [ms]" + (" (log scale)" if log_bins else ""))
    hist_ax.set_ylabel("control steps [count]")
    hist_ax.set_title("distribution of the tracker's solve time", fontsize=10)
    time_ax.set_ylabel("solve time [ms]")
    time_ax.set_title("solve time over the run", fontsize=10)
    time_axis(time_ax)
    for ax in (hist_ax, time_ax):
        style_axes(ax)
        legend(ax, runs)
    if len(title_parts) > 1 and len(set(title_parts)) == 1:  # the same for every run
        title_parts = [f"each: {title_parts[0]}"]
    suptitle(figure, "Tracker solve time — " + (" vs ".join(title_parts) or "no plans"), runs)
    run_legend(figure, runs)
    return save(figure, path)
