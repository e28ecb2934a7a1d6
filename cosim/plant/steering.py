"""The plant's steering actuator: lag, rate limit and clip, Ackermann split, servo command.

The bicycle-model road-wheel angle ``delta`` follows the command through a first-order lag
(time constant ``tau = plant.steer_time_constant_s``, exact discretisation over the step
``dt``: ``delta_lag = u + (delta - u) exp(-dt / tau)``), then a rate limit
(``plant.max_steer_rate_radps``), with the command clipped to ``plant.max_steer_rad``. The
left and right front wheels get their Ackermann angles
(:func:`cosim.plant.sedan_model.ackermann_angles`, front track) through MuJoCo position
servos ``F = kp (ctrl - q) - kv qdot``. Commanding
``ctrl = q_ref + kv/kp qdot_ref + I/kp qddot_ref`` makes the servo force
``kp (q_ref - q) + kv (qdot_ref - qdot) + I qddot_ref``: the wheels follow the actuator
model's output with no lag or overshoot of the servo's own (velocity and acceleration
feed-forward).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from cosim.core.vehicle_params import PlantConfig
from cosim.plant.sedan_model import ackermann_angles


class SteeringActuator:
    """The steering of one plant: :meth:`step` once per physics step writes the two servos'
    commands into MuJoCo's ``ctrl``; :attr:`command_rad` is the latest command."""

    def __init__(self, config: PlantConfig, model: mujoco.MjModel, physics_dt_s: float,
                 servos: tuple[int, int]) -> None:
        self._config = config
        self._dt_s = physics_dt_s
        self.servos = servos
        """The left and right steering servos' actuator indices."""
        tau = config.steer_time_constant_s
        self._decay = math.exp(-physics_dt_s / tau) if tau > 0.0 else 0.0
        self._step_max = config.max_steer_rate_radps * physics_dt_s
        self._front_track_m = config.axle_tracks_m[0]  # the steered wheels' geometry
        left_servo = servos[0]
        kp = float(model.actuator_gainprm[left_servo, 0])
        self._kv_over_kp = -float(model.actuator_biasprm[left_servo, 2]) / kp
        steer_joint = int(model.actuator_trnid[left_servo, 0])
        self._inertia_over_kp = float(model.dof_M0[int(model.jnt_dofadr[steer_joint])]) / kp
        self.reset()

    def constants(self) -> dict[str, float]:
        """The numbers :meth:`step` uses (for the compiled physics step,
        :mod:`cosim.plant.compiled_steps`)."""
        return {"decay": self._decay, "step_max_rad": self._step_max,
                "max_steer_rad": self._config.max_steer_rad,
                "wheelbase_m": self._config.wheelbase_m, "front_track_m": self._front_track_m,
                "kv_over_kp": self._kv_over_kp, "inertia_over_kp": self._inertia_over_kp}

    def reset(self) -> None:
        """Straight ahead, at rest, no command."""
        self.command_rad = 0.0
        self.angle_rad = 0.0
        """The bicycle-model road-wheel angle after lag and rate limit [rad]."""
        self._wheel_rad = (0.0, 0.0)
        self._wheel_rate_radps = (0.0, 0.0)

    def step(self, ctrl: np.ndarray) -> None:
        """Advance the actuator one physics step and set the servos' commands in ``ctrl``."""
        cfg, dt = self._config, self._dt_s
        limit = cfg.max_steer_rad
        target = min(max(self.command_rad, -limit), limit)
        lagged = target + (self.angle_rad - target) * self._decay
        step = min(max(lagged - self.angle_rad, -self._step_max), self._step_max)
        self.angle_rad += step
        left, right = ackermann_angles(self.angle_rad, cfg.wheelbase_m, self._front_track_m)
        (prev_left, prev_right), (prev_rate_left, prev_rate_right) = (
            self._wheel_rad, self._wheel_rate_radps)
        rate_left, rate_right = (left - prev_left) / dt, (right - prev_right) / dt
        kv_kp, i_kp = self._kv_over_kp, self._inertia_over_kp
        ctrl[self.servos[0]] = (
            left + kv_kp * rate_left + i_kp * (rate_left - prev_rate_left) / dt
        )
        ctrl[self.servos[1]] = (
            right + kv_kp * rate_right + i_kp * (rate_right - prev_rate_right) / dt
        )
        self._wheel_rad = (left, right)
        self._wheel_rate_radps = (rate_left, rate_right)
