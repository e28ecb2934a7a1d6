"""Tracking errors over time: cross-track error, heading error, speed against its reference.

CTE is the signed distance of the true CoG from the reference path (by projection, positive
left of the path), heading error the true yaw minus the path's yaw there, as the metrics
define them; the legend repeats each run's max |CTE| and RMS.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cosim.plots.data import RunLog
from cosim.plots.style import (
    REFERENCE_COLOUR,
    finish,
    new_figure,
    note,
    run_colour,
    run_line,
    time_axis,
)

CTE_CM_UP_TO_M = 2.0
"""The cross-track error is drawn in centimetres up to this largest |CTE|, in metres beyond."""


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.nanmean(values**2))) if values.size else float("nan")


def tracking_figure(runs: Sequence[RunLog], path: Path) -> Path:
    figure = new_figure(11.0, 8.5)
    cte_ax, heading_ax, speed_ax = figure.subplots(3, 1, sharex=True)
    reference_speeds: set[float] = set()
    largest_m = max((float(np.nanmax(np.abs(run.tracking.cte_m))) for run in runs
                     if run.tracking is not None and np.any(np.isfinite(run.tracking.cte_m))),
                    default=0.0)
    # Centimetres, unless a run left the path by metres (a spin reads better in metres).
    scale, unit = (100.0, "cm") if largest_m <= CTE_CM_UP_TO_M else (1.0, "m")
    for i, run in enumerate(runs):
        errors = run.tracking
        if errors is None:
            note(cte_ax, f"{run.label}: no /reference/path in the log: no tracking errors")
            continue
        cte = errors.cte_m * scale
        cte_ax.plot(errors.t_s, cte, linewidth=1.2, **run_line(i),
                    label=f"max |CTE| {np.nanmax(np.abs(cte)):.3g} {unit}, "
                          f"RMS {_rms(cte):.3g} {unit}")
        heading_deg = np.degrees(errors.heading_err_rad)
        heading_ax.plot(errors.t_s, heading_deg, linewidth=1.2, **run_line(i),
                        label=f"max {np.nanmax(np.abs(heading_deg)):.2f} deg, "
                              f"RMS {_rms(heading_deg):.2f} deg")
        speed_ax.plot(run.truth.t_s, run.truth.speed_mps, linewidth=1.2, **run_line(i),
                      label=f"true speed (speed error RMS "
                            f"{_rms(errors.speed_err_mps):.2f} m/s)")
        profile = errors.ref_speed_mps
        if np.ptp(profile) > 0.0:  # a speed profile: draw it as it was asked for
            speed_ax.plot(errors.t_s, profile, color=run_colour(i), linestyle=":", linewidth=1.0,
                          label="reference speed profile")
        elif run.reference is not None and run.reference.speed_mps not in reference_speeds:
            reference_speeds.add(run.reference.speed_mps)
            speed_ax.axhline(run.reference.speed_mps, color=REFERENCE_COLOUR, linestyle="--",
                             linewidth=1.0,
                             label=f"reference speed {run.reference.speed_mps:g} m/s")
    for ax in (cte_ax, heading_ax):
        ax.axhline(0.0, color=REFERENCE_COLOUR, linewidth=0.8)
    cte_ax.set_ylabel(f"cross-track error [{unit}]\n(+ = left of path)")
    cte_ax.set_title("cross-track error of the true CoG (projection onto the reference path)",
                     fontsize=10)
    heading_ax.set_ylabel("heading error [deg]")
    heading_ax.set_title("heading error: true yaw - path yaw", fontsize=10)
    speed_ax.set_ylabel("speed [m/s]")
    speed_ax.set_title("speed: true horizontal speed of the CoG vs reference", fontsize=10)
    time_axis(speed_ax)
    return finish(figure, (cte_ax, heading_ax, speed_ax), runs, "Path tracking errors", path)
