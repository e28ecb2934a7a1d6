"""Speed planning along the horizon: slow down before a bend the tyres cannot hold at speed.

The path's reference speed is a wish; on a wet road the bend ahead may not be drivable at
it. The NMPC's horizon (1.25 s) is too short to brake for a bend it only sees once it is in
it, so the reference speed of each stage is capped by the speed from which the car can still
brake, at a moderate deceleration, down to the cornering limit of every bend ahead, the
backward pass of quasi-steady-state speed profiles (Kapania, Subosits and Gerdes, "A
sequential two-step algorithm for fast generation of vehicle racing trajectories", ASME J.
Dynamic Systems, Measurement and Control 138(9), 2016; the same pass as
:func:`tracker.paths.speed_profile.friction_limited`, here over the path ahead of the car at
every control step, with the *believed* friction)::

    v_lim(s) = sqrt(usage_max mu g / |kappa(s)|)                                   (V1)
    v_cap(s_k) = min_{s >= s_k} sqrt(v_lim(s)^2 + 2 brake_usage mu g (s - s_k))      (V2)
    v_ref,k <- min(v_ref,k, v_cap(s_k))                                            (V3)

over the path from the first stage to ``lookahead_s`` at the current speed ahead (and at
least the braking distance from the current speed). The closed form (V2) of the backward
pass is one vectorised minimum, no loop. The path's curvature is tabulated once per path
(:class:`CurvatureTable`, every :data:`GRID_STEP_M`): sampling the spline afresh at every
control step took 0.7 ms, the table lookup a few tens of microseconds. When (V3) lowers any
stage's speed the plan reports ``speed_reduced``.

Most control steps the cap cannot bind: every term of (V2) is at least ``v_lim`` at its own
point, so the cap of every stage is at least the smallest ``v_lim`` over the path ahead,
which the table's largest curvature there bounds from below. Where the fastest reference
speed of the horizon is within that bound, (V3) changes nothing and (V2) is not evaluated
(:func:`capped_reference_speed`): the same speeds, to the bit, at about a third of the
cost of evaluating (V2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracker.models.dynamic_bicycle import GRAVITY_MPS2
from tracker.mpc.grip_config import GripConfig
from tracker.paths.reference_path import ReferencePath

GRID_STEP_M = 1.0
"""Spacing of the curvature samples of the path ahead [m]."""

_MIN_CURVATURE_1PM = 1e-6
"""Curvature below which a path counts as straight (no cornering limit) [1/m]."""

_ROUNDING = 1e-9
"""Relative margin of :meth:`CurvatureTable.most_within` over the tabulated curvature: a
linear interpolation rounds to within a few units in the last place of its neighbours."""


@dataclass(frozen=True)
class SpeedCap:
    """The reference speeds of a horizon after (V3), and whether (V3) lowered any."""

    speed_mps: np.ndarray
    reduced: bool


class CurvatureTable:
    """``|kappa(s)|`` of a path every :data:`GRID_STEP_M`, looked up linearly (periodic on
    a closed path, held at the ends of an open one)."""

    def __init__(self, path: ReferencePath) -> None:
        self.path = path
        self._s_m = np.arange(0.0, path.length_m + GRID_STEP_M, GRID_STEP_M)
        self._kappa_1pm = np.abs(path.sample(self._s_m)["curvature_1pm"])
        self._period_m = path.length_m if path.closed else None

    def __call__(self, s_m: np.ndarray) -> np.ndarray:
        s = self.path.wrap(s_m)
        return np.interp(s, self._s_m, self._kappa_1pm, period=self._period_m)

    def most_within(self, first_m: float, last_m: float) -> float:
        """An upper bound of :meth:`__call__` anywhere in ``[first_m, last_m]``: the largest
        tabulated entry an interpolation there can use (each lies between two neighbouring
        entries), raised by :data:`_ROUNDING` for the interpolation's own rounding."""
        step, count = GRID_STEP_M, self._kappa_1pm.size
        if self._period_m is None:  # held at the ends: the arc lengths clamp first
            first = min(max(first_m, 0.0), self.path.length_m)
            last = min(max(last_m, 0.0), self.path.length_m)
            low = max(int(first // step) - 1, 0)
            high = min(int(-(-last // step)) + 1, count - 1)
            most = float(self._kappa_1pm[low:high + 1].max())
        elif last_m - first_m >= self._period_m - 4.0 * step:
            most = float(self._kappa_1pm.max())
        else:  # entries whose position on the loop is within two steps of the stretch
            ahead = np.mod(self._s_m - first_m, self._period_m)
            near = ((ahead <= last_m - first_m + 2.0 * step)
                    | (ahead >= self._period_m - 2.0 * step))
            most = float(self._kappa_1pm[near].max())
        return most * (1.0 + _ROUNDING)


def cornering_speed_cap(path: ReferencePath | CurvatureTable, stage_s_m: np.ndarray,
                        speed_now_mps: float, friction: float,
                        grip: GripConfig) -> np.ndarray:
    """``v_cap`` of (V2) at the stages' arc lengths ``stage_s_m`` (increasing) [m/s]; the
    path's curvature from ``path`` itself or its table."""
    table = path if isinstance(path, CurvatureTable) else CurvatureTable(path)
    s = np.asarray(stage_s_m, dtype=float)
    decel, lateral, ahead_m = _grip_figures(speed_now_mps, friction, grip)
    grid = np.arange(s[0], s[-1] + ahead_m + GRID_STEP_M, GRID_STEP_M)
    kappa = table(grid)
    limit_sq = lateral / np.maximum(kappa, _MIN_CURVATURE_1PM)  # (V1), squared
    distance = grid[None, :] - s[:, None]
    reachable_sq = np.where(distance >= 0.0, limit_sq[None, :] + 2.0 * decel * distance,
                            np.inf)
    return np.sqrt(np.min(reachable_sq, axis=1))  # (V2)


def _grip_figures(speed_now_mps: float, friction: float,
                  grip: GripConfig) -> tuple[float, float, float]:
    """The braking deceleration of (V2), the lateral acceleration of (V1) [m/s^2] and how
    far beyond the last stage the path is looked at [m]."""
    decel = grip.brake_usage * friction * GRAVITY_MPS2
    lateral = grip.usage_max * friction * GRAVITY_MPS2
    speed = max(float(speed_now_mps), 0.0)
    return decel, lateral, max(grip.lookahead_s * speed, speed * speed / (2.0 * decel))


def cannot_bind(table: CurvatureTable, stage_s_m: np.ndarray, reference_mps: np.ndarray,
                speed_now_mps: float, friction: float, grip: GripConfig) -> bool:
    """Whether (V2) is at least every reference speed for certain (module docstring): the
    fastest of ``reference_mps`` is within ``sqrt(lateral / kappa_max)``, ``kappa_max``
    bounding the curvature at every point of (V2)'s grid from above. Each term of (V2) is
    ``v_lim^2`` plus a distance that is not negative, and rounding keeps every step
    monotone, so the bound holds in floating point too. False for a NaN speed."""
    _, lateral, ahead_m = _grip_figures(speed_now_mps, friction, grip)
    first, last = float(stage_s_m[0]), float(stage_s_m[-1]) + ahead_m + GRID_STEP_M
    kappa_max = max(table.most_within(first, last), _MIN_CURVATURE_1PM)
    return bool(np.max(reference_mps) <= math.sqrt(lateral / kappa_max))


def capped_reference_speed(path: ReferencePath | CurvatureTable, stage_s_m: np.ndarray,
                           reference_mps: np.ndarray, speed_now_mps: float, friction: float,
                           grip: GripConfig) -> SpeedCap:
    """(V3): the stages' reference speeds ``reference_mps`` capped by (V2); where the cap
    :func:`cannot_bind`, the speeds as they are (what (V3) gives them then, to the bit)."""
    table = path if isinstance(path, CurvatureTable) else CurvatureTable(path)
    if cannot_bind(table, stage_s_m, reference_mps, speed_now_mps, friction, grip):
        return SpeedCap(np.array(reference_mps, dtype=float), False)
    cap = cornering_speed_cap(table, stage_s_m, speed_now_mps, friction, grip)
    capped = np.minimum(reference_mps, cap)
    return SpeedCap(capped, bool(np.any(capped < reference_mps)))
