"""Estimation: every estimated state with the filter's own +-3 sigma, NEES, and NIS per sensor.

Two figures: ``estimation.png`` holds the states of the car's motion, with NEES and NIS;
``estimation_internal.png`` the filter's own states (biases, scales, residuals). One panel
per state, in the estimator's order. Where the log has the truth of the same quantity
(pose, velocities, yaw rate, longitudinal acceleration, road-wheel angle, roll, and the
IMU's biases, which the simulated IMU reports) the panel shows the error, estimate minus
truth at the log times both topics share (angles wrapped), inside the band of +-3 sigma
from the diagonal of the logged covariance: a consistent filter keeps its error inside the
band almost always. States with no logged truth (the lateral-force residual, the
rolling-radius and track scales) show the estimate itself with its +-3 sigma band: whether
it settles, and how sure the filter is.

NEES is computed per sample over the states the run metrics use (x, y, yaw, v_x: 4 degrees
of freedom) with the logged covariance block; the shaded band is where 95 % of single-sample
NEES values of a consistent filter fall (chi-square, 4 dof), the dashed line its mean (4).
NIS per sensor (``/estimator/updates``) is each update's normalised innovation squared per
degree of freedom, drawn as its running mean over ``NIS_WINDOW_S``: about 1 for a consistent
filter (Bar-Shalom, Li, Kirubarajan, "Estimation with Applications to Tracking and
Navigation", Wiley 2001, sec. 5.4).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cosim.core.config_fields import unit_of
from cosim.plots.data import TRUTH_FIELDS, RunLog
from cosim.plots.style import (
    REFERENCE_COLOUR,
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
from estimation.consistency import chi_square_quantile

PLOT_UNITS: dict[str, tuple[float, str]] = {
    "m": (100.0, "cm"), "rad": (float(np.degrees(1.0)), "deg"),
    "rad/s": (float(np.degrees(1.0)), "deg/s"),
}
"""SI unit of a state -> (scale, unit) it is plotted in; others are plotted in SI."""

SETTLE_S = 1.0
"""The y range is set by the errors and bands after the filter's first second (at most a
tenth of the run), so the initial convergence from a wide prior does not flatten the rest;
the title says when the start is off scale."""
NIS_WINDOW_S = 1.0
"""Running-mean window of the NIS curves."""
COLUMNS = 2


def _nees_band(dof: int, probability: float = 0.95) -> tuple[float, float]:
    """The central ``probability`` interval of a chi-square(``dof``) variable."""
    tail = (1.0 - probability) / 2.0
    return chi_square_quantile(tail, dof), chi_square_quantile(1.0 - tail, dof)


def _plot_unit(name: str) -> tuple[float, str]:
    si = unit_of(name)
    return PLOT_UNITS.get(si, (1.0, "-" if si == "-" else si))


def _state_names(runs: Sequence[RunLog]) -> list[str]:
    """Every state any run estimates, in the first estimator's order."""
    names: list[str] = []
    for run in runs:
        if run.estimate is not None:
            names += [n for n in run.estimate.state_names if n not in names]
    return names


def _running_mean(t_s: np.ndarray, values: np.ndarray, window_s: float) -> np.ndarray:
    """Mean of ``values`` over the ``window_s`` up to each sample (time-ordered)."""
    sums = np.concatenate(([0.0], np.cumsum(values)))
    first = np.searchsorted(t_s, t_s - window_s, side="right")
    counts = np.arange(1, t_s.size + 1) - first
    return (sums[1:] - sums[first]) / np.maximum(counts, 1)


class _Range:
    """The y extent of a panel: over the whole run, and after the filter settled."""

    def __init__(self) -> None:
        self.settled = 0.0
        self.extreme = 0.0

    def add(self, values: np.ndarray, after: np.ndarray) -> None:
        finite = np.isfinite(values)
        if np.any(finite & after):
            self.settled = max(self.settled, float(np.max(np.abs(values[finite & after]))))
        if np.any(finite):
            self.extreme = max(self.extreme, float(np.max(np.abs(values[finite]))))


def _error_panel(ax: Any, run: RunLog, i: int, name: str, extent: _Range) -> bool:
    """Estimate - truth of ``name`` with +-3 sigma; False when the run has no such error."""
    errors = run.estimation
    if errors is None or name not in errors.error:
        return False
    scale, unit = _plot_unit(name)
    error = errors.error[name] * scale
    sigma3 = 3.0 * errors.sigma[name] * scale
    after = errors.t_s >= errors.t_s[0] + min(SETTLE_S, 0.1 * np.ptp(errors.t_s))
    extent.add(error, after)
    extent.add(sigma3, after)
    inside = np.mean(np.abs(error) <= sigma3) * 100.0
    rmse = float(np.sqrt(np.nanmean(error**2)))
    ax.fill_between(errors.t_s, -sigma3, sigma3, color=run_colour(i), alpha=0.15, linewidth=0,
                    label=f"±3σ (error inside {inside:.1f} %)")
    ax.plot(errors.t_s, error, linewidth=1.0, **run_line(i),
            label=f"estimate - truth (RMS {rmse:.3g} {unit})")
    ax.axhline(0.0, color=REFERENCE_COLOUR, linewidth=0.6)
    return True


def _estimate_panel(ax: Any, run: RunLog, i: int, name: str, extent: _Range) -> bool:
    """The estimate of ``name`` (no truth logged) with its +-3 sigma band."""
    estimate = run.estimate
    if estimate is None or name not in estimate.state_names:
        return False
    scale, unit = _plot_unit(name)
    mean = estimate.column(name) * scale
    sigma3 = 3.0 * estimate.sigma(name) * scale
    after = estimate.t_s >= estimate.t_s[0] + min(SETTLE_S, 0.1 * np.ptp(estimate.t_s))
    extent.add(mean + sigma3, after)
    extent.add(mean - sigma3, after)
    ax.fill_between(estimate.t_s, mean - sigma3, mean + sigma3, color=run_colour(i),
                    alpha=0.15, linewidth=0, label="±3σ")
    ax.plot(estimate.t_s, mean, linewidth=1.0, **run_line(i),
            label=f"estimate (last {mean[-1]:.3g} {unit}; no truth logged)")
    return True


def _nees_panel(ax: Any, runs: Sequence[RunLog]) -> None:
    drawn_bands: set[int] = set()
    nees_values: list[np.ndarray] = []
    for i, run in enumerate(runs):
        errors = run.estimation
        if errors is None or errors.nees is None:
            note(ax, f"{run.label}: NEES not computable (singular or missing covariance, "
                     "e.g. the `truth` estimator)")
            continue
        dof = len(errors.nees_states)
        low, high = _nees_band(dof)
        if dof not in drawn_bands:
            drawn_bands.add(dof)
            ax.axhspan(low, high, color="0.5", alpha=0.15,
                       label=f"95 % band of one sample, χ²({dof}): [{low:.2f}, {high:.2f}]")
            ax.axhline(dof, color=REFERENCE_COLOUR, linestyle="--", linewidth=1.0,
                       label=f"consistent mean = {dof}")
        finite = errors.nees[np.isfinite(errors.nees)]
        mean = float(np.mean(finite)) if finite.size else float("nan")
        outside = 100.0 * np.mean((finite < low) | (finite > high)) if finite.size else 0.0
        nees_values.append(finite)
        ax.plot(errors.t_s, errors.nees, linewidth=0.8, **run_line(i),
                label=f"NEES over {', '.join(errors.nees_states)}: mean {mean:.2f}, "
                      f"{outside:.0f} % outside the band")
    ax.set_yscale("log")
    positive = np.concatenate([v[v > 0] for v in nees_values]) if nees_values else []
    if len(positive):
        # The floor ignores the exact zeros and the lowest percent (NEES of a perfect
        # estimate at t = 0 is 0).
        ax.set_ylim(max(1e-3, 0.5 * float(np.percentile(positive, 1.0))),
                    2.0 * float(np.max(positive)))
    ax.set_ylabel("NEES [-] (log)")
    ax.set_title("NEES: normalised estimation error squared", fontsize=10)


NIS_MARKERS = ("o", "s", "^", "D", "v", "P")


def _nis_panel(ax: Any, runs: Sequence[RunLog]) -> None:
    ax.axhline(1.0, color=REFERENCE_COLOUR, linestyle="--", linewidth=1.0,
               label="consistent mean = 1")
    sensors = sorted({s for run in runs if run.nis for s in run.nis})
    summaries: dict[str, list[str]] = {s: [] for s in sensors}
    lines: dict[str, Any] = {}
    curves: list[np.ndarray] = []
    for i, run in enumerate(runs):
        if not run.nis:
            note(ax, f"{run.label}: no /estimator/updates in the log (older log, or the "
                     "`truth` estimator)")
            continue
        for sensor, nis in run.nis.items():
            if nis.t_s.size == 0:
                continue
            n = sensors.index(sensor)
            mean = _running_mean(nis.t_s, nis.nis_per_dof, NIS_WINDOW_S)
            curves.append(mean)
            gated = int(np.sum(~nis.accepted))
            # The run's own metric (summed NIS over summed channels, gated updates
            # included), so the legend and `nis_<sensor>` agree; a mean of the updates'
            # NIS per dof where the log has no metrics.
            metric = (run.metrics or {}).get(f"nis_{sensor}")
            value = float(metric) if isinstance(metric, (int, float)) else \
                float(np.mean(nis.nis_per_dof))
            summaries[sensor].append(f"{value:.2f}" + (f" ({gated} gated)" if gated else ""))
            (line,) = ax.plot(nis.t_s, mean, linewidth=1.0, linestyle=run_line(i)["linestyle"],
                              marker=NIS_MARKERS[n % len(NIS_MARKERS)],
                              markevery=max(1, mean.size // 12), markersize=4,
                              color=f"C{n + 2}")
            lines.setdefault(sensor, line)
    # One entry per sensor (colour and marker); the runs are the line styles.
    for sensor, line in lines.items():
        line.set_label(f"{sensor}: nis_{sensor} " + " vs ".join(summaries[sensor]))
    positive = np.concatenate([c[c > 0] for c in curves]) if curves else np.empty(0)
    if positive.size:
        ax.set_yscale("log")
        ax.set_ylim(0.5 * float(np.percentile(positive, 1.0)), 2.0 * float(np.max(positive)))
    ax.set_ylabel("NIS / dof [-]" + (" (log)" if ax.get_yscale() == "log" else ""))
    ax.set_title(f"NIS per sensor, per degree of freedom ({NIS_WINDOW_S:g} s running mean)",
                 fontsize=10)


LEGEND_HEADROOM = 0.7
"""Room added above the data for the legend, as a share of the panel's data range (every
panel is full of data from end to end, so the legend goes above it)."""


def _headroom(ax: Any) -> None:
    low, high = ax.get_ylim()
    if ax.get_yscale() == "log":
        ax.set_ylim(low, high * (high / low) ** LEGEND_HEADROOM)
    else:
        ax.set_ylim(low, high + LEGEND_HEADROOM * (high - low))


def _with_truth(runs: Sequence[RunLog], name: str) -> bool:
    """Whether any run logs the truth of state ``name`` (so its error can be drawn)."""
    return any(run.estimation is not None and name in run.estimation.error for run in runs)


def _state_panel(ax: Any, runs: Sequence[RunLog], name: str) -> None:
    """One state's panel: estimate - truth with +-3 sigma, or the estimate and its band."""
    extent = _Range()
    kind = ""
    for i, run in enumerate(runs):
        if _error_panel(ax, run, i, name, extent):
            kind = kind or "error"
        elif _estimate_panel(ax, run, i, name, extent):
            kind = kind or "estimate"
        else:
            note(ax, f"{run.label}: does not estimate {name}")
    _, unit = _plot_unit(name)
    title = f"{name}: " + ("estimate - truth" if kind == "error" else "estimate")
    if 0.0 < extent.settled < extent.extreme / 1.3 and kind == "error":
        ax.set_ylim(-1.3 * extent.settled, 1.3 * extent.settled)
        title += f" (first {SETTLE_S:g} s off scale)"
    ax.set_title(title, fontsize=10)
    ax.set_ylabel(f"[{unit}]")


def _panels_figure(runs: Sequence[RunLog], names: Sequence[str], extra: int) -> tuple[Any, list]:
    """A figure with a panel per state of ``names`` and ``extra`` more, two columns."""
    rows = max(1, -(-(len(names) + extra) // COLUMNS))
    figure = new_figure(16.0, 2.3 * rows + 1.5)
    grid = figure.subplots(rows, COLUMNS, sharex=True, squeeze=False)
    axes = list(grid.ravel())
    for ax, name in zip(axes, names, strict=False):
        _state_panel(ax, runs, name)
    for ax in axes[len(names) + extra:]:
        ax.set_axis_off()
    used = len(names) + extra
    for column in range(COLUMNS):  # the lowest panel in use of each column gets the time
        lowest = max((k for k in range(column, used, COLUMNS)), default=None)
        if lowest is not None:
            axes[lowest].tick_params(labelbottom=True)
            time_axis(axes[lowest])
    return figure, axes


def _finish(figure: Any, axes: list, used: int, runs: Sequence[RunLog], what: str,
            path: Path) -> Path:
    for ax in axes[:used]:
        _headroom(ax)
        style_axes(ax)
        legend(ax, runs, loc="upper right", bbox_to_anchor=None, fontsize=7,
               ncol=2 if len(runs) > 1 else 1)
    suptitle(figure, what, runs)
    run_legend(figure, runs)
    return save(figure, path)


def estimation_figure(runs: Sequence[RunLog], path: Path) -> Path:
    """``estimation.png``: the states the car's truth has (pose, velocities, yaw rate,
    acceleration, road-wheel angle, roll), each as estimate - truth inside the filter's
    +-3 sigma, then NEES and NIS per sensor."""
    names = [n for n in _state_names(runs) if n in TRUTH_FIELDS and _with_truth(runs, n)]
    figure, axes = _panels_figure(runs, names, 2)
    _nees_panel(axes[len(names)], runs)
    _nis_panel(axes[len(names) + 1], runs)
    return _finish(figure, axes, len(names) + 2, runs, "State estimation: the vehicle's states "
                   "(estimate - truth, the filter's ±3σ), NEES and NIS", path)


def estimation_internal_figure(runs: Sequence[RunLog], path: Path) -> Path | None:
    """``estimation_internal.png``: the filter's own states (sensor biases, scale factors,
    residual forces, rates): the error where the truth is logged, else the estimate with
    its +-3 sigma (does it settle, how sure is it); None when the filter has no such state."""
    names = [n for n in _state_names(runs)
             if not (n in TRUTH_FIELDS and _with_truth(runs, n))]
    if not names:
        return None
    figure, axes = _panels_figure(runs, names, 0)
    return _finish(figure, axes, len(names), runs, "State estimation: the filter's internal "
                   "states (biases, scales, residuals) with its ±3σ", path)
