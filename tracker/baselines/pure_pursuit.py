"""``pure-pursuit``: steer the rear axle onto the arc through a look-ahead point.

Coulter, "Implementation of the pure pursuit path tracking algorithm", CMU-RI-TR-92-01,
1992: the goal point lies on the path at distance ``L_d`` from the rear axle; with ``alpha``
the angle from the car's heading to the goal point, the arc from the rear axle through it
has curvature::

    kappa = 2 sin(alpha) / L_d

and the kinematic bicycle turns on it with ``delta = atan(L kappa)``. Here the steady-state
understeer of the belief is added (``delta = atan(L kappa) + K v^2 kappa``), which the
kinematic law lacks and which at 20 m/s on a 40 m radius is 0.6 degrees. The look-ahead is
scheduled by speed, ``L_d = clip(L_min + t_la v, L_min, L_max)`` (Snider 2009, section 2.2):
short look-aheads weave, long ones cut corners. Tuning (``tracker.baseline.pure_pursuit``):
``lookahead_time_s`` 0.6 s, ``lookahead_min_m`` 4 m: 16 m at 20 m/s.
"""

from __future__ import annotations

import math

import numpy as np

from tracker.baselines.common import BaselineTracker, LateralLaw, Pose, bicycle
from tracker.baselines.config import PurePursuitConfig
from tracker.config import TrackerConfig
from tracker.paths.reference_path import ReferencePath, wrap_angle

SEARCH_STEP_M = 0.25
"""Spacing of the arc lengths searched for the goal point [m]."""


def pursuit_curvature(alpha_rad: float, lookahead_m: float) -> float:
    """Coulter's arc: ``2 sin(alpha) / L_d`` [1/m]."""
    return 2.0 * math.sin(alpha_rad) / lookahead_m


def lookahead_m(speed_mps: float, config: PurePursuitConfig) -> float:
    """``clip(L_min + t_la v, L_min, L_max)``."""
    return float(np.clip(config.lookahead_min_m + config.lookahead_time_s * max(speed_mps, 0.0),
                         config.lookahead_min_m, config.lookahead_max_m))


def goal_point(reference: ReferencePath, rear_x_m: float, rear_y_m: float,
               lookahead: float) -> tuple[float, float]:
    """The first path point ahead of the rear axle's projection at ``lookahead`` from it
    (the path's end on an open path that ends sooner)."""
    s0 = reference.project(rear_x_m, rear_y_m).s_m
    s = s0 + np.arange(0.0, 3.0 * lookahead + SEARCH_STEP_M, SEARCH_STEP_M)
    points = reference.sample(s)
    distance = np.hypot(points["x_m"] - rear_x_m, points["y_m"] - rear_y_m)
    beyond = np.flatnonzero(distance >= lookahead)
    i = int(beyond[0]) if beyond.size else len(s) - 1
    return float(points["x_m"][i]), float(points["y_m"][i])


class PurePursuitLaw(LateralLaw):
    def __init__(self, config: TrackerConfig) -> None:
        self._cfg = config.baseline.pure_pursuit
        self._params = bicycle(config)

    def steer(self, pose: Pose, reference: ReferencePath, dt_s: float) -> float:
        lr = self._params.cog_rear_m
        rear_x = pose.x_m - lr * math.cos(pose.yaw_rad)
        rear_y = pose.y_m - lr * math.sin(pose.yaw_rad)
        ld = lookahead_m(pose.vx_mps, self._cfg)
        gx, gy = goal_point(reference, rear_x, rear_y, ld)
        alpha = float(wrap_angle(math.atan2(gy - rear_y, gx - rear_x) - pose.yaw_rad))
        kappa = pursuit_curvature(alpha, math.hypot(gx - rear_x, gy - rear_y) or ld)
        return (math.atan(self._params.wheelbase_m * kappa)
                + self._params.understeer_gradient_radpmps2 * pose.vx_mps**2 * kappa)


def make_pure_pursuit(config: TrackerConfig) -> BaselineTracker:
    return BaselineTracker(config, PurePursuitLaw(config))
