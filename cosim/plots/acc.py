"""Adaptive cruise control over time (``acc.png``, logs with traffic only).

Four panels sharing the time axis: the true gap to the car ahead in the ego's lane with the
ACC's desired gap and the minimum safe gap (the range sensor's target named where it
changes); the ego's and the target's true speeds with the set speed; the ACC's mode (gap
mode shaded) and its commanded acceleration; the three gains as extremum seeking applies
them (thin) and its estimates (thick). Read from ``/traffic/gap``, ``/vehicle/truth``,
``/acc/mode`` and ``/acc/gains``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.log import topics
from cosim.log.reader import iter_topics
from cosim.plots.data import RunLog
from cosim.plots.style import finish, new_figure, note, run_colour, run_line, time_axis

ACC_TOPICS = {topics.TRAFFIC_GAP, topics.ACC_MODE, topics.ACC_GAINS}
GAIN_NAMES = ("k_v", "k_x", "k_vrel")
GAIN_UNITS = {"k_v": "1/s", "k_x": "1/s^2", "k_vrel": "1/s"}


@dataclass(frozen=True)
class AccLog:
    """The ACC's topics of one log as arrays (NaN where a value was null)."""

    gap_t_s: np.ndarray
    gap_m: np.ndarray
    safe_gap_m: np.ndarray
    target_speed_mps: np.ndarray
    targets: list[str]
    mode_t_s: np.ndarray
    gap_mode: np.ndarray
    desired_gap_m: np.ndarray
    accel_mps2: np.ndarray
    gains_t_s: np.ndarray
    gains: dict[str, np.ndarray]
    gain_estimates: dict[str, np.ndarray]


def _floats(messages: list[dict[str, Any]], name: str) -> np.ndarray:
    return np.array([math.nan if m.get(name) is None else float(m[name]) for m in messages])


def load_acc(path: Path) -> AccLog | None:
    """The ACC topics of the log at ``path``; None when it has no traffic."""
    messages: dict[str, list[dict[str, Any]]] = {topic: [] for topic in ACC_TOPICS}
    for topic, _, message in iter_topics(path, ACC_TOPICS):
        messages[topic].append(message)
    gap, mode, gains = (messages[t] for t in (topics.TRAFFIC_GAP, topics.ACC_MODE,
                                              topics.ACC_GAINS))
    if not gap:
        return None
    return AccLog(
        gap_t_s=_floats(gap, "t_s"), gap_m=_floats(gap, "gap_m"),
        safe_gap_m=_floats(gap, "safe_gap_m"),
        target_speed_mps=_floats(gap, "target_speed_mps"),
        targets=[str(m.get("target", "")) for m in gap],
        mode_t_s=_floats(mode, "t_s"),
        gap_mode=np.array([bool(m.get("gap_mode")) for m in mode], dtype=bool),
        desired_gap_m=_floats(mode, "desired_gap_m"), accel_mps2=_floats(mode, "accel_mps2"),
        gains_t_s=_floats(gains, "t_s"),
        gains={n: _floats(gains, n) for n in GAIN_NAMES},
        gain_estimates={n: _floats(gains, f"{n}_estimate") for n in GAIN_NAMES})


def _shade_gap_mode(ax: Any, log: AccLog, colour: str) -> None:
    """Shade the intervals in gap mode."""
    if not log.gap_mode.size:
        return
    edges = np.flatnonzero(np.diff(np.r_[False, log.gap_mode, False].astype(int)))
    t = np.r_[log.mode_t_s, log.mode_t_s[-1]]
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        ax.axvspan(t[start], t[stop], color=colour, alpha=0.12, linewidth=0)


def acc_figure(runs: Sequence[RunLog], logs: Sequence[AccLog], path: Path) -> Path:
    """Gap, speeds, mode and acceleration, gains (module docstring)."""
    figure = new_figure(11.0, 11.0)
    axes = figure.subplots(4, 1, sharex=True)
    gap_ax, speed_ax, mode_ax, gain_ax = axes
    for index, (run, log) in enumerate(zip(runs, logs, strict=True)):
        colour, line = run_colour(index), {"linestyle": run_line(index)["linestyle"]}

        def label(text: str, index: int = index) -> str | None:
            return text if index == 0 else None  # the run legend tells the runs apart
        gap_ax.plot(log.gap_t_s, log.gap_m, color=colour, linewidth=1.6,
                    label=label("true gap"), **line)
        gap_ax.plot(log.gap_t_s, log.safe_gap_m, color="tab:red", linewidth=1.0,
                    label=label("minimum safe gap"), **line)
        if log.mode_t_s.size:
            gap_ax.plot(log.mode_t_s, log.desired_gap_m, color="0.4", linewidth=1.0,
                        label=label("desired gap (d0 + h v)"), **line)
        last_target = log.targets[0] if log.targets else ""
        for i in range(1, len(log.targets)):
            if log.targets[i] and log.targets[i] != last_target:  # a new car ahead
                last_target = log.targets[i]
                gap_ax.axvline(log.gap_t_s[i], color="0.5", linewidth=0.8)
                gap_ax.annotate(f"target: {log.targets[i]}", (log.gap_t_s[i], 0.98),
                                xycoords=("data", "axes fraction"), fontsize=8,
                                va="top", ha="left")
        speed_ax.plot(run.truth.t_s, run.truth.speed_mps, color=colour, linewidth=1.6,
                      label=label("ego speed"), **line)
        speed_ax.plot(log.gap_t_s, log.target_speed_mps, color="tab:orange", linewidth=1.2,
                      label=label("target's speed"), **line)
        set_speed = run.config.get("tracker", {}).get("acc", {}).get("set_speed_mps")
        if set_speed is not None:
            speed_ax.axhline(set_speed, color="0.4", linewidth=1.0, linestyle=":",
                             label=label("set speed"))
        if log.mode_t_s.size:
            _shade_gap_mode(mode_ax, log, colour)
            mode_ax.plot(log.mode_t_s, log.accel_mps2, color=colour, linewidth=1.2,
                         label=label("commanded acceleration (gap mode shaded)"), **line)
        for gain, gain_colour in zip(GAIN_NAMES, ("tab:blue", "tab:green", "tab:purple"),
                                     strict=True):
            if not log.gains_t_s.size:
                continue
            gain_ax.plot(log.gains_t_s, log.gains[gain], color=gain_colour, linewidth=0.6,
                         alpha=0.6, **line)
            gain_ax.plot(log.gains_t_s, log.gain_estimates[gain], color=gain_colour,
                         linewidth=2.0, label=label(f"{gain} [{GAIN_UNITS[gain]}]"), **line)
    if not any(log.gains_t_s.size for log in logs):
        note(gain_ax, "no ACC in this run (no /acc/gains)")
    gap_ax.set_ylabel("gap [m]")
    speed_ax.set_ylabel("speed [m/s]")
    mode_ax.set_ylabel("acceleration [m/s^2]")
    gain_ax.set_ylabel("gain")
    time_axis(gain_ax)
    return finish(figure, list(axes), runs, "Adaptive cruise control", path)
