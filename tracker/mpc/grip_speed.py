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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.models.dynamic_bicycle import GRAVITY_MPS2
from tracker.mpc.grip_config import GripConfig
from tracker.paths.reference_path import ReferencePath

GRID_STEP_M = 1.0
"""Spacing of the curvature samples of the path ahead [m]."""

_MIN_CURVATURE_1PM = 1e-6
"""Curvature below which a path counts as straight (no cornering limit) [1/m]."""


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


def cornering_speed_cap(path: ReferencePath | CurvatureTable, stage_s_m: np.ndarray,
                        speed_now_mps: float, friction: float,
                        grip: GripConfig) -> np.ndarray:
    """``v_cap`` of (V2) at the stages' arc lengths ``stage_s_m`` (increasing) [m/s]; the
    path's curvature from ``path`` itself or its table."""
    table = path if isinstance(path, CurvatureTable) else CurvatureTable(path)
    s = np.asarray(stage_s_m, dtype=float)
    decel = grip.brake_usage * friction * GRAVITY_MPS2
    lateral = grip.usage_max * friction * GRAVITY_MPS2
    speed = max(float(speed_now_mps), 0.0)
    ahead_m = max(grip.lookahead_s * speed, speed * speed / (2.0 * decel))
    grid = np.arange(s[0], s[-1] + ahead_m + GRID_STEP_M, GRID_STEP_M)
    kappa = table(grid)
    limit_sq = lateral / np.maximum(kappa, _MIN_CURVATURE_1PM)  # (V1), squared
    distance = grid[None, :] - s[:, None]
    reachable_sq = np.where(distance >= 0.0, limit_sq[None, :] + 2.0 * decel * distance,
                            np.inf)
    return np.sqrt(np.min(reachable_sq, axis=1))  # (V2)


def capped_reference_speed(path: ReferencePath | CurvatureTable, stage_s_m: np.ndarray,
                           reference_mps: np.ndarray, speed_now_mps: float, friction: float,
                           grip: GripConfig) -> SpeedCap:
    """(V3): the stages' reference speeds ``reference_mps`` capped by (V2)."""
    cap = cornering_speed_cap(path, stage_s_m, speed_now_mps, friction, grip)
    capped = np.minimum(reference_mps, cap)
    return SpeedCap(capped, bool(np.any(capped < reference_mps)))
