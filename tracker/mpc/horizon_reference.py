"""The reference an MPC tracks over its horizon: points, headings and curvature.

Two ways (``tracker.reference``), both giving one reference point per stage, at the arc
length the car is expected to have covered by then (``s_k = s_0 + sum v_j dt``, with the
speeds ``v_j`` of the warm start):

* ``spline`` (default): the car is projected onto the path, itself a cubic spline in arc
  length (:class:`tracker.paths.reference_path.ReferencePath`), and the points are read off the
  spline, with its exact heading and curvature.
* ``cubic-polynomial``: the common way of tutorial kinematic MPCs. Waypoints of the path around the
car
  (one per metre, from ``BEHIND_M`` behind to the end of the horizon plus ``AHEAD_M``) are
  turned into the vehicle frame and fitted by least squares with one cubic
  ``y = c0 + c1 x + c2 x^2 + c3 x^3``; the points are laid along that cubic at the same
  arc lengths, with its heading ``atan(y')`` and curvature ``y'' / (1 + y'^2)^1.5``. One
  cubic cannot follow both swings of a lane change inside one horizon, which is why it is
  not the default. Where the waypoints fold back in the vehicle frame (a turn of more than
  90 degrees within the window), no function ``y(x)`` exists and the spline is used.

Headings are unwrapped along the horizon and shifted by whole turns to within pi of the
car's yaw, so the NLP can difference them without wrapping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cosim.core.exceptions import ConfigError
from tracker.paths.reference_path import ReferencePath, path_curvature

REFERENCE_KINDS: tuple[str, ...] = ("spline", "cubic-polynomial")
"""Values of ``tracker.reference``."""

BEHIND_M = 5.0
"""Waypoints behind the car's projection that the polynomial fit includes [m]."""

AHEAD_M = 5.0
"""Waypoints beyond the end of the horizon that the polynomial fit includes [m]."""

_WAYPOINT_SPACING_M = 1.0


@dataclass(frozen=True)
class HorizonReference:
    """Reference points for stages 1..N (world frame, ENU)."""

    x_m: np.ndarray
    y_m: np.ndarray
    yaw_rad: np.ndarray
    curvature_1pm: np.ndarray
    s_m: np.ndarray
    """Arc length on the path of each stage (where its reference speed is read) [m]."""

    def speed_mps(self, path: ReferencePath, t_s: float, dt_s: float) -> np.ndarray:
        """The path's reference speed at each stage's arc length and time
        (stage ``k`` at ``t_s + k dt_s``, k = 1..N)."""
        times = t_s + dt_s * np.arange(1, self.s_m.size + 1)
        return path.speed_ref(self.s_m, times)


def _rebased_yaw(yaw_rad: np.ndarray, first_rad: float, car_yaw_rad: float) -> np.ndarray:
    """Unwrap ``first, yaw...`` and shift by whole turns so ``first`` is near the car.

    Where no step between neighbours reaches pi (a horizon's headings nearly always), the
    unwrap (``np.unwrap``) changes nothing but adds its zero corrections, done here
    directly: the same numbers, without ``np.unwrap``'s general machinery. The turns are
    counted in plain floats (Python's ``round`` halves to even, as ``np.round`` does)."""
    first_rad = float(first_rad)
    first_step = abs(float(yaw_rad[0]) - first_rad) if yaw_rad.size else 0.0
    steps = float(np.abs(yaw_rad[1:] - yaw_rad[:-1]).max(initial=0.0))  # np.diff's
    if first_step < math.pi and steps < math.pi:  # False for a NaN: np.unwrap carries it
        unwrapped = yaw_rad + 0.0  # np.unwrap's zero correction (it turns -0.0 into 0.0)
    else:
        unwrapped = np.unwrap(np.concatenate(([first_rad], yaw_rad)))[1:]
    turns = (float(car_yaw_rad) - first_rad) / (2.0 * math.pi)
    if math.isfinite(turns):
        turns = float(round(turns))
    return unwrapped + 2.0 * math.pi * turns


def spline_reference(path: ReferencePath, s_m: np.ndarray, first_yaw_rad: float,
                     car_yaw_rad: float) -> HorizonReference:
    """The path itself at the arc lengths ``s_m``."""
    samples = path.sample(s_m)
    return HorizonReference(samples["x_m"], samples["y_m"],
                            _rebased_yaw(samples["yaw_rad"], first_yaw_rad, car_yaw_rad),
                            samples["curvature_1pm"], np.asarray(s_m, dtype=float))


def polynomial_reference(path: ReferencePath, s0_m: float, distances_m: np.ndarray,
                         x_m: float, y_m: float, yaw_rad: float) -> HorizonReference | None:
    """A cubic in the vehicle frame, sampled at ``distances_m`` along it
    from the car's projection; None where the waypoints fold back (no ``y(x)``)."""
    end_m = s0_m + float(distances_m[-1]) + AHEAD_M
    if path.closed:  # a circuit: arc lengths wrap
        s = np.arange(s0_m - BEHIND_M, end_m, _WAYPOINT_SPACING_M)
    else:
        s = np.arange(max(0.0, s0_m - BEHIND_M), min(path.length_m, end_m),
                      _WAYPOINT_SPACING_M)
    if s.size < 4:
        return None
    waypoints = path.sample(s)
    c, si = np.cos(yaw_rad), np.sin(yaw_rad)
    dx, dy = waypoints["x_m"] - x_m, waypoints["y_m"] - y_m
    x_v, y_v = c * dx + si * dy, -si * dx + c * dy
    if np.any(np.diff(x_v) <= 0.0):
        return None
    poly = np.polynomial.Polynomial.fit(x_v, y_v, 3).convert()
    slope, bend = poly.deriv(1), poly.deriv(2)
    # Arc length along the cubic from the car's abscissa, tabulated finely (trapezoids).
    start = float(c * (path.point(s0_m).x_m - x_m) + si * (path.point(s0_m).y_m - y_m))
    table_x = np.linspace(start, x_v[-1], 2000)
    speed = np.hypot(1.0, slope(table_x))
    table_s = np.concatenate(([0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1])
                                               * np.diff(table_x))))
    xs = np.interp(distances_m, table_s, table_x)
    ys = poly(xs)
    heading = np.arctan(slope(xs))
    curvature = bend(xs) / (1.0 + slope(xs) ** 2) ** 1.5
    first_heading = float(np.arctan(slope(start)))
    return HorizonReference(
        x_m=x_m + c * xs - si * ys,
        y_m=y_m + si * xs + c * ys,
        yaw_rad=_rebased_yaw(yaw_rad + heading, yaw_rad + first_heading, yaw_rad),
        curvature_1pm=curvature,
        s_m=s0_m + np.asarray(distances_m, dtype=float),
    )


def horizon_reference(kind: str, path: ReferencePath, x_m: float, y_m: float, yaw_rad: float,
                      speeds_mps: np.ndarray, dt_s: float) -> HorizonReference:
    """Reference points for the N stages of a horizon (N + 1 ``speeds_mps``, one per node).

    The car at ``(x_m, y_m, yaw_rad)`` is projected onto ``path``; stage ``k``'s point lies
    ``sum_{j<=k} (v_j + v_{j+1}) / 2 * dt_s`` further along (trapezoids over the warm
    start's speeds, negative speeds counted as zero).
    """
    if kind not in REFERENCE_KINDS:
        raise ConfigError(f"tracker.reference = {kind!r}: expected one of "
                          f"{', '.join(REFERENCE_KINDS)}")
    if kind == "spline":  # one C call where a compiler works (tracker.paths.compiled_path)
        compiled = path.compiled_horizon(x_m, y_m, speeds_mps, dt_s)
        if compiled is not None:
            projection, (s_m, x_ref, y_ref, dx, dy, ddx, ddy) = compiled
            return HorizonReference(
                x_ref, y_ref, _rebased_yaw(np.arctan2(dy, dx), projection.path_yaw_rad, yaw_rad),
                path_curvature(dx, dy, ddx, ddy), s_m)
    projection = path.project(x_m, y_m)
    speed = np.maximum(np.asarray(speeds_mps, dtype=float), 0.0)
    distances = np.cumsum(0.5 * (speed[:-1] + speed[1:]) * dt_s)
    if kind == "cubic-polynomial":
        fitted = polynomial_reference(path, projection.s_m, distances, x_m, y_m, yaw_rad)
        if fitted is not None:
            return fitted
    return spline_reference(path, projection.s_m + distances, projection.path_yaw_rad,
                            yaw_rad)
