"""Commands against their limits: steering angle, steering rate, acceleration.

The commands are those applied to the plant (``/control/command``, after the actuator delay
line), drawn as the zero-order hold they are; the plant's response (the true road-wheel
angle and the CoG's longitudinal acceleration) is drawn thin beside them. Limits are the
tracker's, from the run's config (``tracker.max_steer_rad``; a log written before that was
one key holds dynamic-mpc's own bound too, and the tighter counts). A limit far outside the
signal's range is not drawn
(it would flatten the signal) but stated in the panel with the share of it the run used.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.plots.data import RunLog
from cosim.plots.style import (
    LIMIT_COLOUR,
    finish,
    generic,
    new_figure,
    note,
    run_colour,
    run_line,
    time_axis,
)

OFF_SCALE_FACTOR = 2.5
"""A limit beyond this many times the signal's largest magnitude is stated, not drawn."""


@dataclass(frozen=True)
class Limits:
    """A run's command limits (SI), from its logged config."""

    steer_rad: float | None
    steer_rate_radps: float | None
    accel_min_mps2: float | None
    accel_max_mps2: float | None


def tracker_limits(config: dict[str, Any]) -> Limits:
    tracker = config.get("tracker", {})
    steer = tracker.get("max_steer_rad")
    if tracker.get("name") == "dynamic-mpc" and steer is not None:
        own = tracker.get("dynamic_mpc", {}).get("max_steer_rad")
        steer = min(steer, own) if own is not None else steer
    return Limits(steer, tracker.get("max_steer_rate_radps"), tracker.get("accel_min_mps2"),
                  tracker.get("accel_max_mps2"))


def _draw_limits(ax: Any, values: list[tuple[float, float]], data: list[np.ndarray],
                 unit: str, what: str) -> None:
    """Dashed lines at each distinct (low, high) pair, or a legend entry when off scale."""
    finite = [d[np.isfinite(d)] for d in data if d.size]
    peak = max((float(np.max(np.abs(d))) for d in finite if d.size), default=0.0)
    for low, high in sorted(set(values)):
        bound = max(abs(low), abs(high))
        if peak > 0.0 and bound > OFF_SCALE_FACTOR * peak:
            share = 100.0 * peak / bound
            ax.plot([], [], color=LIMIT_COLOUR, linestyle="--", linewidth=1.0,
                    label=f"{what} [{low:g}, {high:g}] {unit}: off scale, the peak is "
                          f"{share:.0f} % of it")
            continue
        ax.axhline(low, color=LIMIT_COLOUR, linestyle="--", linewidth=1.0)
        ax.axhline(high, color=LIMIT_COLOUR, linestyle="--", linewidth=1.0,
                   label=f"{what} [{low:g}, {high:g}] {unit}")


def commands_figure(runs: Sequence[RunLog], path: Path) -> Path:
    figure = new_figure(11.0, 9.0)
    steer_ax, rate_ax, accel_ax = figure.subplots(3, 1, sharex=True)
    steer_limits, rate_limits, accel_limits = [], [], []
    steer_data, rate_data, accel_data = [], [], []
    for i, run in enumerate(runs):
        colour = run_colour(i)
        commands = run.commands
        limits = tracker_limits(run.config)
        if limits.steer_rad is not None:
            bound = round(float(np.degrees(limits.steer_rad)), 2)
            steer_limits.append((-bound, bound))
        if limits.steer_rate_radps is not None:
            bound = round(float(np.degrees(limits.steer_rate_radps)), 1)
            rate_limits.append((-bound, bound))
        if limits.accel_min_mps2 is not None and limits.accel_max_mps2 is not None:
            accel_limits.append((limits.accel_min_mps2, limits.accel_max_mps2))
        steer_ax.plot(run.truth.t_s, np.degrees(run.truth.steer_rad), color=colour,
                      linewidth=0.8, alpha=0.6, linestyle=":",
                      label=generic(i, "road-wheel angle (plant, true)"))
        accel_ax.plot(run.truth.t_s, run.truth.ax_mps2, color=colour, linewidth=0.8,
                      alpha=0.6, linestyle=":", label=generic(i, "CoG longitudinal accel. (true)"))
        if commands is None:
            note(steer_ax, f"{run.label}: no /control/command messages")
            continue
        steer_deg = np.degrees(commands.steer_rad)
        steer_ax.step(commands.t_s, steer_deg, where="post", **run_line(i), linewidth=1.3,
                      label=f"command (peak |angle| {np.nanmax(np.abs(steer_deg)):.2f} deg)")
        steer_data.append(steer_deg)
        if commands.t_s.size > 1:
            rate = np.diff(steer_deg) / np.diff(commands.t_s)
            rate_ax.step(commands.t_s[1:], rate, where="pre", **run_line(i), linewidth=1.2,
                         label=f"command rate (peak |rate| "
                               f"{np.nanmax(np.abs(rate)):.1f} deg/s)")
            rate_data.append(rate)
        accel_ax.step(commands.t_s, commands.accel_mps2, where="post", **run_line(i),
                      linewidth=1.3, label=generic(i, "command"))
        accel_data.append(commands.accel_mps2)
    _draw_limits(steer_ax, steer_limits, steer_data, "deg", "tracker limit")
    _draw_limits(rate_ax, rate_limits, rate_data, "deg/s", "tracker rate limit")
    _draw_limits(accel_ax, accel_limits, accel_data, "m/s²", "tracker limits")
    steer_ax.set_ylabel("road-wheel angle [deg]\n(+ = left)")
    steer_ax.set_title("steering command (as applied, after the delay line)", fontsize=10)
    rate_ax.set_ylabel("steering rate [deg/s]")
    rate_ax.set_title("steering command rate (difference per control period)", fontsize=10)
    accel_ax.set_ylabel("acceleration [m/s²]")
    accel_ax.set_title("longitudinal acceleration command", fontsize=10)
    time_axis(accel_ax)
    return finish(figure, (steer_ax, rate_ax, accel_ax), runs, "Commands and their limits",
                  path)
