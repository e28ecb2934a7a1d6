"""Pure pursuit with a speed-scheduled look-ahead and a proportional speed loop.

Steering (Coulter, CMU-RI-TR-92-01, 1992): the goal point is the path point a look-ahead
distance ``L_d`` ahead of the rear axle; with ``alpha`` its bearing from the heading, the
rear axle's arc through it has curvature ``kappa = 2 sin(alpha) / L_d`` and a kinematic
bicycle of wheelbase ``L`` follows it with ``delta = atan(L kappa)``. Speed: ``a = k_v
(v_ref - v)``, clipped to the tracker's acceleration bounds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cosim.core.config_fields import setting
from cosim.core.records import Command, Estimate, Plan


class PurePursuit:
    """A tracker from outside cosim: built as ``PurePursuit(params, config)``."""

    @dataclass(frozen=True)
    class Params:
        """``tracker.params``: validated by cosim against these settings."""

        lookahead_time_s: float = setting(0.4, low=0.0, high=5.0,
                                          doc="look-ahead per m/s of speed")
        lookahead_min_m: float = setting(4.0, low=0.5, high=50.0, doc="shortest look-ahead")
        speed_gain_1ps: float = setting(1.0, low=0.0, high=20.0,
                                        doc="acceleration per m/s of speed error")

    def __init__(self, params: PurePursuit.Params, config: Any) -> None:
        self.params = params
        self.wheelbase_m = config.model.wheelbase_m
        self.cog_rear_m = config.model.cog_rear_m
        self.max_steer_rad = config.max_steer_rad
        self.accel_bounds_mps2 = (config.accel_min_mps2, config.accel_max_mps2)
        self.dt_s = config.dt_s

    def reset(self) -> None:
        """Nothing to forget: the law has no memory."""

    def step(self, t_s: float, estimate: Estimate, reference: Any) -> tuple[Command, Plan]:
        x, y, yaw = estimate["x_m"], estimate["y_m"], estimate["yaw_rad"]
        speed = estimate["vx_mps"]
        rear_x = x - self.cog_rear_m * math.cos(yaw)
        rear_y = y - self.cog_rear_m * math.sin(yaw)
        lookahead = self.params.lookahead_min_m + self.params.lookahead_time_s * max(speed, 0)
        s0 = reference.project(rear_x, rear_y).s_m
        ahead = reference.sample(s0 + np.linspace(0.0, 3.0 * lookahead, 120))
        reach = np.hypot(ahead["x_m"] - rear_x, ahead["y_m"] - rear_y)
        far = np.flatnonzero(reach >= lookahead)
        i = int(far[0]) if far.size else len(reach) - 1
        bearing = math.atan2(ahead["y_m"][i] - rear_y, ahead["x_m"][i] - rear_x) - yaw
        alpha = math.atan2(math.sin(bearing), math.cos(bearing))
        kappa = 2.0 * math.sin(alpha) / max(float(reach[i]), 1e-3)
        steer = float(np.clip(math.atan(self.wheelbase_m * kappa),
                              -self.max_steer_rad, self.max_steer_rad))
        v_ref = float(reference.speed_ref(s0, t_s))
        accel = float(np.clip(self.params.speed_gain_1ps * (v_ref - speed),
                              *self.accel_bounds_mps2))
        plan = Plan(t_s=t_s, dt_s=self.dt_s, state_names=("x_m", "y_m"),
                    states=np.array([[x, y], [ahead["x_m"][i], ahead["y_m"][i]]]),
                    input_names=("accel_mps2", "steer_rad"),
                    inputs=np.array([[accel, steer]]), cost=0.0, solve_time_s=0.0,
                    iterations=0, status="pure pursuit", success=True, fallback=False)
        return Command(t_s, accel, steer), plan
