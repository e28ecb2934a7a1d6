"""``stanley``: the Stanford Racing Team's steering law.

Thrun et al., "Stanley: the robot that won the DARPA Grand Challenge", J. Field Robotics
23(9), 2006, section 9.2; Hoffmann, Tomlin, Montemerlo and Thrun, "Autonomous automobile
trajectory tracking for off-road driving: controller design, experimental validation and
racing", American Control Conference 2007, eq. (4)-(7)::

    delta = -e_psi,f - atan(k e_f / (k_soft + v)) - k_d,yaw (r - r_ref) + delta_ff

``e_f`` is the cross-track error of the *front axle* (positive left, hence the minus signs in
ISO 8855), ``e_psi,f`` the heading error against the path's tangent at the front axle's
projection, ``k_soft`` keeps the gain finite at standstill, ``k_d,yaw`` damps the yaw rate
against the path's (``r_ref = v kappa``, Hoffmann's yaw-damping term for speed). For the
steady yaw offset in a turn (Hoffmann's ``psi_ss``) this implementation uses the curvature
feed-forward every baseline here has (:mod:`tracker.baselines.common`). Tuning
(``tracker.baseline.stanley``): ``gain`` 1.5 1/s, ``softening_mps`` 1 m/s,
``yaw_rate_damping`` 0.1 s.
"""

from __future__ import annotations

import math

from tracker.baselines.common import (
    BaselineTracker,
    LateralLaw,
    Pose,
    bicycle,
    curvature_feedforward,
)
from tracker.config import TrackerConfig
from tracker.paths.reference_path import ReferencePath, wrap_angle


def stanley_steer(heading_error_rad: float, front_cte_m: float, speed_mps: float,
                  gain: float, softening_mps: float, yaw_rate_error_radps: float = 0.0,
                  yaw_rate_damping_s: float = 0.0) -> float:
    """Stanley's law without feed-forward (module docstring)."""
    return (-heading_error_rad
            - math.atan(gain * front_cte_m / (softening_mps + max(speed_mps, 0.0)))
            - yaw_rate_damping_s * yaw_rate_error_radps)


class StanleyLaw(LateralLaw):
    def __init__(self, config: TrackerConfig) -> None:
        self._cfg = config.baseline.stanley
        self._params = bicycle(config)

    def steer(self, pose: Pose, reference: ReferencePath, dt_s: float) -> float:
        lf = self._params.cog_front_m
        front = reference.project(pose.x_m + lf * math.cos(pose.yaw_rad),
                                  pose.y_m + lf * math.sin(pose.yaw_rad))
        heading_error = float(wrap_angle(pose.yaw_rad - front.path_yaw_rad))
        yaw_rate_error = pose.yaw_rate_radps - pose.vx_mps * front.curvature_1pm
        ff = curvature_feedforward(front.curvature_1pm, pose.vx_mps, self._params)
        return ff + stanley_steer(heading_error, front.lateral_error_m, pose.vx_mps,
                                  self._cfg.gain, self._cfg.softening_mps, yaw_rate_error,
                                  self._cfg.yaw_rate_damping)


def make_stanley(config: TrackerConfig) -> BaselineTracker:
    return BaselineTracker(config, StanleyLaw(config))
