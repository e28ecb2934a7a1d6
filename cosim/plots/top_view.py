"""Top view of the run: the car's path against the reference, at true scale and magnified.

A lane change is hundreds of metres long and a few metres wide, and a good tracker stays
within centimetres of the path, so one picture cannot show everything. Four panels:

1. true scale (equal aspect): the whole driven stretch and the car's footprint every
   second;
2. the manoeuvre (where the reference curves) with the lateral axis stretched (the factor
   is in the title): reference, true and estimated CoG path, the MPC's predicted paths at
   a few instants (a dot marks where each starts);
3. the same stretch in path coordinates: lateral offset from the reference [cm] along x,
   for the true CoG, the estimate and the predicted paths (each point projected onto the
   path): this is where centimetre deviations and the predictions' quality show;
4. at the instant of the largest |CTE| (over the runs): the car at true scale with a few
   metres around it, and a true-scale close-up in centimetres around the reference point
   nearest the CoG, with the CTE as an arrow, the estimate and the predicted path.

The footprint is the simulated body's outline (``cosim.plant.sedan_model``): wheelbase plus an
overhang of ``OVERHANG_M`` at each end, the wider track plus 0.2 m, centred between the axles; its
front edge is drawn heavier. Plans without world-frame ``x_m``/``y_m`` states have no
predicted paths; the panels say so (``dynamic-mpc`` adds them to its path-error plans).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cosim.plant.sedan_model import OVERHANG_M
from cosim.plots.data import Plans, RunLog
from cosim.plots.style import (
    ESTIMATE_COLOUR,
    FONT_SIZE,
    REFERENCE_COLOUR,
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
)

FOOTPRINT_PERIOD_S = 1.0
"""Time between drawn footprints."""
PREDICTIONS = 6
"""How many predicted paths are drawn."""
MANOEUVRE_CURVATURE_SHARE = 0.05
"""The manoeuvre is where the reference's |curvature| exceeds this share of its largest
|curvature| over the driven stretch."""
MANOEUVRE_MARGIN_M = 15.0
ZOOM_HALF_WIDTH_M = 6.0
DEVIATION_TITLE = "deviation from the reference"
CLOSE_UP_CM_UP_TO_M = 5.0
"""The close-up is drawn in centimetres up to this half-width, in metres beyond."""
LARGE_CTE_SHARE = 0.5
"""The stretched and deviation panels cover every x where |CTE| reaches this share of its
largest value (beyond the manoeuvre's curves if need be)."""


def footprint(config: dict[str, Any], x_m: float, y_m: float, yaw_rad: float) -> np.ndarray:
    """Corners (4, 2) of the body outline in the world frame: front-left, front-right,
    rear-right, rear-left (the front edge is corners 0-1)."""
    plant = config.get("plant", {})
    cog_front, cog_rear = plant.get("cog_front_m", 1.2), plant.get("cog_rear_m", 1.6)
    half_length = 0.5 * (cog_front + cog_rear) + OVERHANG_M
    track = plant.get("track_m", 1.6)  # each axle's own track where it is set (not 0)
    widest = max(plant.get("track_front_m", 0.0) or track, plant.get("track_rear_m", 0.0) or track)
    half_width = 0.5 * widest + 0.1
    centre = 0.5 * (cog_front - cog_rear)
    body = np.array([[centre + half_length, half_width], [centre + half_length, -half_width],
                     [centre - half_length, -half_width], [centre - half_length, half_width]])
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return body @ np.array([[c, s], [-s, c]]) + np.array([x_m, y_m])


def _driven_window(run: RunLog) -> tuple[float, float]:
    return float(np.nanmin(run.truth.x_m)), float(np.nanmax(run.truth.x_m))


def _manoeuvre_window(runs: Sequence[RunLog]) -> tuple[float, float]:
    """x range where the reference curves (with a margin), within the driven range."""
    low = min(_driven_window(run)[0] for run in runs)
    high = max(_driven_window(run)[1] for run in runs)
    reference = runs[0].reference
    if reference is None:
        return low, high
    samples = reference.path.sample(np.arange(0.0, reference.path.length_m, 0.5))
    inside = (samples["x_m"] >= low) & (samples["x_m"] <= high)
    curvature = np.abs(samples["curvature_1pm"])
    if not np.any(inside) or np.max(curvature[inside]) <= 0.0:
        return low, high
    curving = inside & (curvature > MANOEUVRE_CURVATURE_SHARE * np.max(curvature[inside]))
    if not np.any(curving):
        return low, high
    x = samples["x_m"][curving]
    return max(low, float(x.min()) - MANOEUVRE_MARGIN_M), min(high, float(x.max())
                                                            + MANOEUVRE_MARGIN_M)


def _deviation_window(runs: Sequence[RunLog], x_low: float, x_high: float
                      ) -> tuple[float, float]:
    """``[x_low, x_high]`` widened to every x where a run's |CTE| reaches
    ``LARGE_CTE_SHARE`` of its largest, so the deviation panel shows the worst of the run
    (a car that spins after the manoeuvre's curves spins in the picture too)."""
    for run in runs:
        if run.tracking is None:
            continue
        cte = np.abs(run.tracking.cte_m)
        finite = np.isfinite(cte) & np.isfinite(run.truth.x_m)
        if not np.any(finite):
            continue
        large = finite & (cte >= LARGE_CTE_SHARE * float(np.max(cte[finite])))
        x_low = min(x_low, float(np.min(run.truth.x_m[large])) - 2.0)
        x_high = max(x_high, float(np.max(run.truth.x_m[large])) + 2.0)
    return x_low, x_high


def _reference_xy(run: RunLog, low: float, high: float) -> tuple[np.ndarray, np.ndarray]:
    reference = run.reference
    if reference is None:
        return np.empty(0), np.empty(0)
    samples = reference.path.sample(np.arange(0.0, reference.path.length_m, 0.25))
    keep = (samples["x_m"] >= low - 5.0) & (samples["x_m"] <= high + 5.0)
    return samples["x_m"][keep], samples["y_m"][keep]


def _prediction_indices(plans: Plans, t_low: float, t_high: float) -> list[int]:
    times = np.linspace(t_low, t_high, PREDICTIONS + 2)[1:-1]
    return sorted({int(np.argmin(np.abs(plans.t_s - t))) for t in times})


def _time_window(run: RunLog, x_low: float, x_high: float) -> tuple[float, float]:
    inside = (run.truth.x_m >= x_low) & (run.truth.x_m <= x_high)
    if not np.any(inside):
        return float(run.truth.t_s[0]), float(run.truth.t_s[-1])
    return float(run.truth.t_s[inside][0]), float(run.truth.t_s[inside][-1])


def _footprint_indices(run: RunLog, x_low: float, x_high: float,
                       period_s: float = FOOTPRINT_PERIOD_S) -> list[int]:
    t = run.truth.t_s
    marks = np.arange(t[0], t[-1] + 1e-9, period_s)
    indices = {int(np.argmin(np.abs(t - mark))) for mark in marks}
    return sorted(i for i in indices if x_low - 5.0 <= run.truth.x_m[i] <= x_high + 5.0)


def _draw_footprint(ax: Any, run: RunLog, index: int, colour: str, alpha: float,
                    label: str | None = None) -> None:
    from matplotlib.patches import Polygon

    corners = footprint(run.config, run.truth.x_m[index], run.truth.y_m[index],
                        run.truth.yaw_rad[index])
    ax.add_patch(Polygon(corners, closed=True, facecolor=colour, edgecolor=colour,
                         alpha=alpha, linewidth=0.8, label=label))
    ax.plot(corners[:2, 0], corners[:2, 1], color=colour, linewidth=2.0, alpha=0.9)


def _clip(x: np.ndarray, y: np.ndarray, low: float, high: float
          ) -> tuple[np.ndarray, np.ndarray]:
    """The points with ``low <= x <= high`` (so they do not stretch the y range)."""
    keep = (x >= low) & (x <= high)
    return x[keep], y[keep]


def _lateral_offsets(run: RunLog, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    reference = run.reference
    if reference is None:
        return np.full(x.shape, np.nan)
    return np.array([reference.path.project(px, py).lateral_error_m
                     if np.isfinite(px) and np.isfinite(py) else np.nan
                     for px, py in zip(x, y, strict=True)])


def _no_predictions_text(run: RunLog) -> str | None:
    plans = run.plans
    if plans is None:
        return f"{run.label}: no /control/plan messages: no predicted paths"
    if not plans.has_positions:
        states = ", ".join(n for n in plans.state_names if n.endswith(("_m", "_rad")))
        return (f"{run.label}: no predicted paths (the plan predicts {states}; "
                "no world-frame x_m, y_m)")
    return None


def _true_scale_panel(ax: Any, runs: Sequence[RunLog]) -> None:
    low = min(_driven_window(run)[0] for run in runs)
    high = max(_driven_window(run)[1] for run in runs)
    ref_x, ref_y = _reference_xy(runs[0], low, high)
    ax.plot(ref_x, ref_y, color=REFERENCE_COLOUR, linestyle="--", linewidth=1.0,
            label="reference path")
    for i, run in enumerate(runs):
        colour = run_colour(i)
        ax.plot(run.truth.x_m, run.truth.y_m, linewidth=1.2, **run_line(i),
                label=generic(i, "true CoG path"))
        for n, index in enumerate(_footprint_indices(run, low, high)):
            _draw_footprint(ax, run, index, colour, 0.25,
                            generic(i, f"footprint every {FOOTPRINT_PERIOD_S:g} s")
                            if n == 0 else None)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (east) [m]")
    ax.set_ylabel("y (north) [m]")
    ax.set_title("true scale (equal axes)", fontsize=10)


def _stretched_panel(ax: Any, runs: Sequence[RunLog], x_low: float, x_high: float) -> None:
    ref_x, ref_y = _reference_xy(runs[0], x_low, x_high)
    inside = (ref_x >= x_low) & (ref_x <= x_high)
    ax.plot(ref_x[inside], ref_y[inside], color=REFERENCE_COLOUR, linestyle="--",
            linewidth=1.2, label="reference path")
    missing = []
    for i, run in enumerate(runs):
        colour = run_colour(i)
        ax.plot(*_clip(run.truth.x_m, run.truth.y_m, x_low, x_high), **run_line(i),
                linewidth=1.4, label=generic(i, "true CoG path"))
        if run.estimate is not None:
            ax.plot(*_clip(run.estimate.column("x_m"), run.estimate.column("y_m"), x_low,
                           x_high),
                    color=ESTIMATE_COLOUR if len(runs) == 1 else colour, linewidth=0.9,
                    linestyle=":", label=generic(i, "estimated CoG path"))
        text = _no_predictions_text(run)
        if text:
            missing.append(text)
            continue
        plans = run.plans
        assert plans is not None
        t_low, t_high = _time_window(run, x_low, x_high)
        for n, k in enumerate(_prediction_indices(plans, t_low, t_high)):
            horizon_s = plans.dt_s[k] * (plans.predicted[k]["x_m"].size - 1)
            px, py = _clip(plans.predicted[k]["x_m"], plans.predicted[k]["y_m"], x_low,
                           x_high)
            ax.plot(px, py, color=colour, linewidth=1.0, linestyle=(0, (4, 2)), alpha=0.9,
                    label=generic(i, f"MPC predicted path (horizon {horizon_s:.2g} s)")
                    if n == 0 else None)
            ax.plot(px[:1], py[:1], marker="o", markersize=3, color=colour)
    if missing:
        note(ax, "\n".join(missing), loc="lower left")
    ax.set_xlim(x_low, x_high)
    ax.set_xlabel("x (east) [m]")
    ax.set_ylabel("y (north) [m]")


def _path_coordinates_panel(ax: Any, runs: Sequence[RunLog], x_low: float,
                            x_high: float) -> None:
    ax.axhline(0.0, color=REFERENCE_COLOUR, linestyle="--", linewidth=1.2,
               label="reference path")
    for i, run in enumerate(runs):
        colour = run_colour(i)
        keep = (run.truth.x_m >= x_low) & (run.truth.x_m <= x_high)
        if run.tracking is None:
            note(ax, f"{run.label}: no reference path in the log")
            continue
        ax.plot(run.truth.x_m[keep], run.tracking.cte_m[keep] * 100.0, **run_line(i),
                linewidth=1.4, label=generic(i, "true CoG"))
        if run.estimate is not None:
            ex, ey = run.estimate.column("x_m"), run.estimate.column("y_m")
            keep_e = (ex >= x_low) & (ex <= x_high)
            step = max(1, int(np.sum(keep_e)) // 600)
            ex, ey = ex[keep_e][::step], ey[keep_e][::step]
            ax.plot(ex, _lateral_offsets(run, ex, ey) * 100.0,
                    color=ESTIMATE_COLOUR if len(runs) == 1 else colour, linewidth=0.9,
                    linestyle=":", label=generic(i, "estimated CoG"))
        plans = run.plans
        if plans is None or not plans.has_positions:
            continue
        t_low, t_high = _time_window(run, x_low, x_high)
        for n, k in enumerate(_prediction_indices(plans, t_low, t_high)):
            px, py = _clip(plans.predicted[k]["x_m"], plans.predicted[k]["y_m"], x_low,
                           x_high)
            offsets = _lateral_offsets(run, px, py) * 100.0
            ax.plot(px, offsets, color=colour, linewidth=1.0, linestyle=(0, (4, 2)),
                    alpha=0.9, label=generic(i, "MPC predicted path") if n == 0 else None)
            ax.plot(px[:1], offsets[:1], marker="o", markersize=3, color=colour)
    ax.set_xlim(x_low, x_high)
    ax.set_xlabel("x (east) [m]")
    ax.set_ylabel("lateral offset from\nthe reference [cm] (+ = left)")
    ax.set_title(f"{DEVIATION_TITLE}, in path coordinates (projection onto the path)",
                 fontsize=10)


def _largest_cte(runs: Sequence[RunLog]) -> tuple[RunLog, float] | None:
    """The run and time of the largest |CTE| over the runs."""
    best: tuple[RunLog, float, float] | None = None
    for run in runs:
        if run.tracking is None or not np.any(np.isfinite(run.tracking.cte_m)):
            continue
        k = int(np.nanargmax(np.abs(run.tracking.cte_m)))
        value = float(abs(run.tracking.cte_m[k]))
        if best is None or value > best[2]:
            best = (run, float(run.tracking.t_s[k]), value)
    return None if best is None else (best[0], best[1])


def _car_zoom_panel(ax: Any, runs: Sequence[RunLog], centre: RunLog, t_s: float) -> None:
    """True scale, a few car lengths around ``centre``'s car at ``t_s``."""
    index = int(np.argmin(np.abs(centre.truth.t_s - t_s)))
    cx, cy = centre.truth.x_m[index], centre.truth.y_m[index]
    ref_x, ref_y = _reference_xy(centre, cx - 2 * ZOOM_HALF_WIDTH_M,
                                 cx + 2 * ZOOM_HALF_WIDTH_M)
    ax.plot(ref_x, ref_y, color=REFERENCE_COLOUR, linestyle="--", linewidth=1.0,
            label="reference path")
    for i, run in enumerate(runs):
        colour = run_colour(i)
        k = int(np.argmin(np.abs(run.truth.t_s - t_s)))
        near = np.abs(run.truth.x_m - cx) < 2 * ZOOM_HALF_WIDTH_M
        ax.plot(run.truth.x_m[near], run.truth.y_m[near], linewidth=1.2, **run_line(i),
                label=generic(i, "true CoG path"))
        _draw_footprint(ax, run, k, colour, 0.2, generic(i, "footprint"))
        plans = run.plans
        if plans is not None and plans.has_positions:
            p = int(np.argmin(np.abs(plans.t_s - t_s)))
            ax.plot(plans.predicted[p]["x_m"], plans.predicted[p]["y_m"], color=colour,
                    linestyle=(0, (4, 2)), linewidth=1.0,
                    label=generic(i, f"MPC predicted path (t = {plans.t_s[p]:.2f} s)"))
    ax.set_xlim(cx - ZOOM_HALF_WIDTH_M, cx + ZOOM_HALF_WIDTH_M)
    ax.set_ylim(cy - 0.6 * ZOOM_HALF_WIDTH_M, cy + 0.6 * ZOOM_HALF_WIDTH_M)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (east) [m]")
    ax.set_ylabel("y (north) [m]")
    ax.set_title(f"true scale around the car at t = {t_s:.2f} s", fontsize=10)


def _close_up_panel(ax: Any, runs: Sequence[RunLog], centre: RunLog, t_s: float) -> None:
    """True scale in centimetres (metres for a car metres off) around the reference point
    nearest to ``centre``'s CoG at ``t_s``: the CTE as an arrow, the estimate, the
    predicted path's first metres."""
    assert centre.reference is not None and centre.tracking is not None

    def origin_of(run: RunLog) -> tuple[float, float]:
        """The reference point nearest to the run's CoG at ``t_s``: each run is drawn
        around its own, so runs that are apart along the path still overlay their CTE."""
        tracking = run.tracking if run.tracking is not None else centre.tracking
        reference = run.reference if run.reference is not None else centre.reference
        k = int(np.argmin(np.abs(run.truth.t_s - t_s)))
        point = reference.path.point(float(tracking.s_m[min(k, len(tracking.s_m) - 1)]))
        return point.x_m, point.y_m

    ox, oy = origin_of(centre)
    offsets = []
    for run in runs:
        if run.tracking is not None:
            k = int(np.argmin(np.abs(run.truth.t_s - t_s)))
            rx, ry = origin_of(run)
            offsets.append(np.hypot(run.truth.x_m[k] - rx, run.truth.y_m[k] - ry))
    half_m = max(0.1, 2.5 * max(offsets, default=0.0))
    # Centimetres for a close-up; metres once the car is metres off (a spin).
    scale, unit = (100.0, "cm") if half_m <= CLOSE_UP_CM_UP_TO_M else (1.0, "m")
    half = half_m * scale
    s0 = float(centre.reference.path.project(ox, oy).s_m)
    ref = centre.reference.path.sample(np.linspace(s0 - 3 * half_m, s0 + 3 * half_m, 50))
    ax.plot((ref["x_m"] - ox) * scale, (ref["y_m"] - oy) * scale, color=REFERENCE_COLOUR,
            linestyle="--", linewidth=1.2, label="reference path")
    for i, run in enumerate(runs):
        colour = run_colour(i)
        rx, ry = origin_of(run)
        k = int(np.argmin(np.abs(run.truth.t_s - t_s)))
        near = np.hypot(run.truth.x_m - rx, run.truth.y_m - ry) < 4 * half_m
        ax.plot((run.truth.x_m[near] - rx) * scale, (run.truth.y_m[near] - ry) * scale,
                linewidth=1.2, **run_line(i), label=generic(i, "true CoG path"))
        px, py = (run.truth.x_m[k] - rx) * scale, (run.truth.y_m[k] - ry) * scale
        cte_text = (f"CTE {run.tracking.cte_m[k] * scale:+.{1 if unit == 'cm' else 2}f} {unit}"
                    if run.tracking is not None else "")
        ax.annotate("", xy=(px, py), xytext=(0.0, 0.0),
                    arrowprops={"arrowstyle": "->", "color": colour, "linewidth": 1.5})
        ax.plot(px, py, marker="o", color=colour, markersize=6, linestyle="none",
                label=generic(i, f"true CoG at t = {t_s:.2f} s"))
        # Labels stacked in the panel's corner: arrows of several runs never hide them.
        ax.text(0.02, 0.96 - 0.08 * i, cte_text, transform=ax.transAxes, color=colour,
                fontsize=FONT_SIZE, va="top", ha="left")
        if run.estimate is not None:
            e = int(np.argmin(np.abs(run.estimate.t_s - t_s)))
            ax.plot((run.estimate.column("x_m")[e] - rx) * scale,
                    (run.estimate.column("y_m")[e] - ry) * scale, marker="x",
                    color=ESTIMATE_COLOUR if len(runs) == 1 else colour, markersize=8,
                    markeredgewidth=2, linestyle="none", label=generic(i, "estimated CoG"))
        plans = run.plans
        if plans is not None and plans.has_positions:
            p = int(np.argmin(np.abs(plans.t_s - t_s)))
            ax.plot((plans.predicted[p]["x_m"] - rx) * scale,
                    (plans.predicted[p]["y_m"] - ry) * scale, color=colour,
                    linestyle=(0, (4, 2)), linewidth=1.0, marker=".", markersize=4,
                    label=generic(i, f"MPC predicted path (t = {plans.t_s[p]:.2f} s)"))
    ax.set_xlim(-half, half)
    ax.set_ylim(-0.6 * half, 0.6 * half)
    ax.set_aspect("equal", adjustable="box")
    if len(runs) == 1:
        ax.set_xlabel(f"x {'-' if ox >= 0 else '+'} {abs(ox):.2f} m [{unit}]")
        ax.set_ylabel(f"y {'-' if oy >= 0 else '+'} {abs(oy):.2f} m [{unit}]")
    else:  # each run around its own nearest reference point
        ax.set_xlabel(f"x east of each run's nearest reference point [{unit}]")
        ax.set_ylabel(f"y north of it [{unit}]")
    ax.set_title(f"close-up (true scale, {unit}) at the largest |CTE|, t = {t_s:.2f} s",
                 fontsize=10)


def _stretch_factor(ax: Any) -> float:
    """How much more a metre spans vertically than horizontally in ``ax``."""
    box = ax.get_window_extent()
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    return float((box.height / abs(y1 - y0)) / (box.width / abs(x1 - x0)))


def top_view_figure(runs: Sequence[RunLog], path: Path) -> Path:
    return save(top_view(runs), path)


def _is_circuit(runs: Sequence[RunLog]) -> bool:
    """Whether the runs follow a closed path: its x folds the straights onto each other."""
    return any(run.reference is not None and run.reference.path.closed for run in runs)


def _lap_deviation_panel(ax: Any, runs: Sequence[RunLog]) -> None:
    """A circuit's deviation against the distance along the path (each lap over the last):
    x would fold a lap's straights onto each other."""
    ax.axhline(0.0, color=REFERENCE_COLOUR, linestyle="--", linewidth=1.2,
               label="reference path")
    for i, run in enumerate(runs):
        if run.tracking is None:
            note(ax, f"{run.label}: no reference path in the log")
            continue
        s_m, cte = run.tracking.s_m, run.tracking.cte_m * 100.0
        breaks = np.flatnonzero(np.diff(s_m) < 0.0) + 1  # a new lap starts at s = 0
        for n, (a, b) in enumerate(zip(np.r_[0, breaks], np.r_[breaks, s_m.size],
                                       strict=True)):
            ax.plot(s_m[a:b], cte[a:b], **run_line(i), linewidth=1.2,
                    alpha=1.0 if n == 0 else 0.6,
                    label=generic(i, "true CoG" + (", each lap" if breaks.size else ""))
                    if n == 0 else None)
    ax.set_xlabel("distance along the path s [m] (each lap from its start)")
    ax.set_ylabel("lateral offset from\nthe reference [cm] (+ = left)")
    ax.set_title(f"{DEVIATION_TITLE}, in path coordinates, along the lap", fontsize=10)


def top_view(runs: Sequence[RunLog]) -> Any:
    """The top-view figure (a ``matplotlib.figure.Figure``); the deviation panel's title
    starts with ``DEVIATION_TITLE``. A circuit (a closed path) gets the whole circuit at true
    scale and the deviation along the lap instead of the manoeuvre's panels against x."""
    if _is_circuit(runs):
        return _circuit_view(runs)
    figure = new_figure(12.0, 15.0)
    grid = figure.add_gridspec(4, 2, height_ratios=[1.0, 2.4, 2.2, 2.8])
    true_ax = figure.add_subplot(grid[0, :])
    stretched_ax = figure.add_subplot(grid[1, :])
    frenet_ax = figure.add_subplot(grid[2, :], sharex=stretched_ax)
    car_ax, close_ax = figure.add_subplot(grid[3, 0]), figure.add_subplot(grid[3, 1])
    x_low, x_high = _deviation_window(runs, *_manoeuvre_window(runs))
    _true_scale_panel(true_ax, runs)
    _stretched_panel(stretched_ax, runs, x_low, x_high)
    _path_coordinates_panel(frenet_ax, runs, x_low, x_high)
    for ax in (true_ax, stretched_ax, frenet_ax):
        style_axes(ax)
        legend(ax, runs)
    _close_ups(car_ax, close_ax, runs)
    figure.canvas.draw()
    stretched_ax.set_title("the manoeuvre, lateral axis stretched "
                           f"x{_stretch_factor(stretched_ax):.0f}", fontsize=10)
    suptitle(figure, "Top view: path vs reference", runs)
    run_legend(figure, runs)
    return figure


def _circuit_view(runs: Sequence[RunLog]) -> Any:
    figure = new_figure(12.0, 15.0)
    grid = figure.add_gridspec(3, 2, height_ratios=[3.2, 2.0, 2.8])
    true_ax = figure.add_subplot(grid[0, :])
    lap_ax = figure.add_subplot(grid[1, :])
    car_ax, close_ax = figure.add_subplot(grid[2, 0]), figure.add_subplot(grid[2, 1])
    _true_scale_panel(true_ax, runs)
    _lap_deviation_panel(lap_ax, runs)
    for ax in (true_ax, lap_ax):
        style_axes(ax)
        legend(ax, runs)
    _close_ups(car_ax, close_ax, runs)
    suptitle(figure, "Top view: path vs reference (a circuit)", runs)
    run_legend(figure, runs)
    return figure


def _close_ups(car_ax: Any, close_ax: Any, runs: Sequence[RunLog]) -> None:
    """The car at true scale and the close-up in centimetres, at the largest |CTE| (both
    panels off when no run has a tracking error)."""
    largest = _largest_cte(runs)
    if largest is None:
        car_ax.set_axis_off()
        close_ax.set_axis_off()
        return
    _car_zoom_panel(car_ax, runs, *largest)
    _close_up_panel(close_ax, runs, *largest)
    for ax in (car_ax, close_ax):
        style_axes(ax)
        legend(ax, runs, loc="upper center", bbox_to_anchor=(0.5, -0.24), ncol=2)
