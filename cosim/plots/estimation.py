"""Estimation errors with the filter's own +-3 sigma, and NEES.

Errors are estimate minus truth at the log times both topics share (yaw wrapped); the band
is +-3 sigma from the diagonal of the logged covariance, so a consistent filter keeps its
error inside the band almost always. NEES is computed per sample over the states the run
metrics use (x, y, yaw, v_x: 4 degrees of freedom) with the logged covariance block; the
shaded band is where 95 % of single-sample NEES values of a consistent filter fall
(chi-square, 4 dof), the dashed line its mean (4).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cosim.plots.data import RunLog
from cosim.plots.style import (
    REFERENCE_COLOUR,
    legend,
    new_figure,
    note,
    run_colour,
    run_legend,
    save,
    style_axes,
    suptitle,
    time_axis,
)

PANELS = (
    ("x_m", 100.0, "cm", "x error [cm]", "position error, x (east)"),
    ("y_m", 100.0, "cm", "y error [cm]", "position error, y (north)"),
    ("yaw_rad", float(np.degrees(1.0)), "deg", "yaw error [deg]", "yaw error"),
    ("vx_mps", 1.0, "m/s", "v_x error [m/s]", "longitudinal speed error (vehicle frame)"),
)
"""(state, scale from SI to the plotted unit, the unit, y label, title)."""

SETTLE_S = 1.0
"""The y range is set by the errors and bands after the filter's first second (at most a
tenth of the run), so the initial convergence from a wide prior does not flatten the rest;
the title says when the start is off scale."""


def _nees_band(dof: int, probability: float = 0.95) -> tuple[float, float]:
    from scipy.stats import chi2

    tail = (1.0 - probability) / 2.0
    return float(chi2.ppf(tail, dof)), float(chi2.ppf(1.0 - tail, dof))


def estimation_figure(runs: Sequence[RunLog], path: Path) -> Path:
    figure = new_figure(11.0, 12.0)
    axes = figure.subplots(len(PANELS) + 1, 1, sharex=True)
    nees_ax = axes[-1]
    drawn_bands: set[int] = set()
    settled = [0.0] * len(PANELS)
    extreme = [0.0] * len(PANELS)
    nees_values: list[np.ndarray] = []
    for i, run in enumerate(runs):
        colour = run_colour(i)
        errors = run.estimation
        if errors is None:
            note(axes[0], f"{run.label}: no /vehicle/estimate at the truth's log times")
            continue
        after = errors.t_s >= errors.t_s[0] + min(SETTLE_S, 0.1 * np.ptp(errors.t_s))
        for p, (ax, (name, scale, unit, _, _)) in enumerate(zip(axes, PANELS,
                                                                  strict=False)):
            if name not in errors.error:
                note(ax, f"{run.label}: the estimator does not estimate {name}")
                continue
            error = errors.error[name] * scale
            sigma3 = 3.0 * errors.sigma[name] * scale
            inside = np.mean(np.abs(error) <= sigma3) * 100.0
            rmse = float(np.sqrt(np.nanmean(error**2)))
            if np.any(after):
                settled[p] = max(settled[p], float(np.nanmax(np.abs(error[after]))),
                                 float(np.nanmax(sigma3[after])))
            extreme[p] = max(extreme[p], float(np.nanmax(np.abs(error))),
                             float(np.nanmax(sigma3)))
            ax.fill_between(errors.t_s, -sigma3, sigma3, color=colour, alpha=0.15,
                            linewidth=0, label=f"±3σ (error inside {inside:.1f} %)")
            ax.plot(errors.t_s, error, color=colour, linewidth=1.0,
                    label=f"estimate - truth (RMS {rmse:.3g} {unit})")
        if errors.nees is None:
            note(nees_ax, f"{run.label}: NEES not computable (singular or missing "
                          "covariance, e.g. the `truth` estimator)")
            continue
        dof = len(errors.nees_states)
        low, high = _nees_band(dof)
        if dof not in drawn_bands:
            drawn_bands.add(dof)
            nees_ax.axhspan(low, high, color="0.5", alpha=0.15,
                            label=f"95 % band of one sample, χ²({dof}): "
                                  f"[{low:.2f}, {high:.2f}]")
            nees_ax.axhline(dof, color=REFERENCE_COLOUR, linestyle="--", linewidth=1.0,
                            label=f"consistent mean = {dof}")
        finite = errors.nees[np.isfinite(errors.nees)]
        mean = float(np.mean(finite)) if finite.size else float("nan")
        outside = 100.0 * np.mean((finite < low) | (finite > high)) if finite.size else 0.0
        nees_values.append(finite)
        nees_ax.plot(errors.t_s, errors.nees, color=colour,
                     linewidth=0.8,
                     label=f"NEES over {', '.join(errors.nees_states)}: mean "
                           f"{mean:.2f}, {outside:.0f} % outside the band")
    for p, (ax, (_, _, _, ylabel, title)) in enumerate(zip(axes, PANELS, strict=False)):
        ax.axhline(0.0, color=REFERENCE_COLOUR, linewidth=0.6)
        ax.set_ylabel(ylabel)
        if 0.0 < settled[p] < extreme[p] / 1.3:
            ax.set_ylim(-1.3 * settled[p], 1.3 * settled[p])
            title += f" (the first {SETTLE_S:g} s, the filter converging, is off scale)"
        ax.set_title(title, fontsize=10)
    nees_ax.set_yscale("log")
    positive = np.concatenate([v[v > 0] for v in nees_values]) if nees_values else []
    if len(positive):
        # Headroom above the data for the legend; the floor ignores the exact zeros and the
        # lowest percent (NEES of a perfect estimate at t = 0 is 0).
        nees_ax.set_ylim(max(1e-3, 0.5 * float(np.percentile(positive, 1.0))),
                         40.0 * float(np.max(positive)))
    nees_ax.set_ylabel("NEES [-] (log scale)")
    nees_ax.set_title("normalised estimation error squared (filter consistency)", fontsize=10)
    time_axis(nees_ax)
    for ax in axes:
        style_axes(ax)
        legend(ax, runs, loc="upper right", ncol=2 if ax is nees_ax else 1)
    suptitle(figure, "State estimation error (estimate - truth) with the filter's ±3σ", runs)
    run_legend(figure, runs)
    return save(figure, path)
