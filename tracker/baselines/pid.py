"""``pid``: a lateral PID on the cross-track error with a heading term, and curvature
feed-forward; the speed loop of :mod:`tracker.baselines.common`.

    delta = delta_ff(kappa) - k_p e - k_i int(e) dt - k_d e' - k_psi e_psi

with ``e`` the CTE of the centre of gravity (positive left, so a positive error steers
right), ``e' = v_x sin e_psi + v_y cos e_psi`` its rate from the estimate (not a
differentiated noisy CTE), ``e_psi`` the heading error. This is the textbook loop the
lateral-control literature compares against (e.g. Snider, "Automatic steering methods for
autonomous automobile path tracking", CMU-RI-TR-09-08, 2009, section 2; Rajamani 2012,
section 3.2, whose state feedback on ``e1, e1', e2`` is the same structure). The integral is
clamped (anti-windup). Tuning (``tracker.baseline.pid``): ``kp_cte`` 0.15 rad/m, ``kd_cte``
0.08 rad s/m and ``k_heading`` 0.8 damp the lane change at 20 m/s without weaving on the
straight; the small ``ki_cte`` removes the offset that a wrong cornering-stiffness belief
leaves on a circle.
"""

from __future__ import annotations

import math

import numpy as np

from tracker.baselines.common import (
    BaselineTracker,
    LateralLaw,
    Pose,
    bicycle,
    curvature_feedforward,
)
from tracker.config import TrackerConfig
from tracker.paths.reference_path import ReferencePath


def pid_steer(cte_m: float, cte_rate_mps: float, cte_integral_ms: float,
              heading_error_rad: float, feedforward_rad: float, kp: float, ki: float,
              kd: float, k_heading: float) -> float:
    """The PID law of the module docstring."""
    return (feedforward_rad - kp * cte_m - ki * cte_integral_ms - kd * cte_rate_mps
            - k_heading * heading_error_rad)


class PidLaw(LateralLaw):
    def __init__(self, config: TrackerConfig) -> None:
        self._cfg = config.baseline.pid
        self._params = bicycle(config)
        self._integral = 0.0

    def reset(self) -> None:
        self._integral = 0.0

    def steer(self, pose: Pose, reference: ReferencePath, dt_s: float) -> float:
        cfg = self._cfg
        e = pose.projection.lateral_error_m
        e_psi = pose.heading_error_rad
        self._integral = float(np.clip(self._integral + e * dt_s, -cfg.integral_limit_ms,
                                       cfg.integral_limit_ms))
        rate = pose.vx_mps * math.sin(e_psi) + pose.vy_mps * math.cos(e_psi)
        ff = curvature_feedforward(pose.projection.curvature_1pm, pose.vx_mps, self._params)
        return pid_steer(e, rate, self._integral, e_psi, ff, cfg.kp_cte, cfg.ki_cte,
                         cfg.kd_cte, cfg.k_heading)


def make_pid(config: TrackerConfig) -> BaselineTracker:
    return BaselineTracker(config, PidLaw(config))
