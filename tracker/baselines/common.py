"""What the baseline trackers share: the pose they steer from, the speed loop, the plan.

A baseline is a law ``steer = f(pose, path)`` (:class:`LateralLaw`) inside
:class:`BaselineTracker`, which gives it the same surroundings as the MPCs:

* the estimate, predicted over the believed actuator delay (``tracker.latency_s``) when
  ``tracker.latency_compensation`` is on, with a constant-turn model at the estimated speed
  and yaw rate (the MPCs predict with their own models and the commands in the delay line;
  a law without a model gets the simplest honest prediction);
* the same bounds: ``|delta| <= tracker.max_steer_rad``, ``|d delta/dt| <=
  tracker.max_steer_rate_radps``, ``accel_min_mps2 <= a <= accel_max_mps2``;
* a longitudinal PI on the speed error (``tracker.baseline.speed``) with the reference
  profile's acceleration as feed-forward, and a standstill hold while the reference rests;
* the steady-state steering of the path's curvature as feed-forward, ``delta_ff = L kappa +
  K v^2 kappa`` with the belief's understeer gradient ``K`` (Rajamani 2012, eq. 3.15 without
  the small-angle ``atan``; the MPCs use the same term), where the law itself has no
  such term (pure pursuit and LQR have their own);
* a :class:`cosim.core.records.Plan` with two nodes (now and one control period ahead on a
  kinematic bicycle) and one input, so logs, plots and metrics treat it like an MPC's.

A non-finite estimate commands a safe stop (steering held, ``tracker.safe_stop_accel_mps2``)
and counts as a fallback.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from cosim.core.records import Command, Estimate, Plan
from tracker.config import TrackerConfig
from tracker.models.dynamic_bicycle import DynamicBicycleParams
from tracker.paths.reference_path import Projection, ReferencePath, wrap_angle

PLAN_STATES = ("x_m", "y_m", "yaw_rad", "vx_mps")
"""The plan's state columns."""
PLAN_INPUTS = ("accel_mps2", "steer_rad")
"""The plan's input columns (the :class:`Command` fields)."""
ACCEL_FEEDFORWARD_S = 0.5
"""Time over which the speed profile's slope is read for the acceleration feed-forward [s]."""
STANDSTILL_GAIN_PER_S = 2.0
"""While the reference stands still (now and ``ACCEL_FEEDFORWARD_S`` ahead), brake at least
this times the remaining speed, so the car comes to rest instead of creeping on the PI's
small residual error [1/s]."""


@dataclass(frozen=True)
class Pose:
    """What a lateral law steers from: the (predicted) car and its projection on the path."""

    t_s: float
    x_m: float
    y_m: float
    yaw_rad: float
    vx_mps: float
    vy_mps: float
    yaw_rate_radps: float
    projection: Projection

    @property
    def heading_error_rad(self) -> float:
        """Yaw minus the path's yaw at the projection, wrapped to (-pi, pi]."""
        return float(wrap_angle(self.yaw_rad - self.projection.path_yaw_rad))


class LateralLaw:
    """A steering law; :meth:`steer` returns the road-wheel angle before the bounds."""

    def steer(self, pose: Pose, reference: ReferencePath, dt_s: float) -> float:
        raise NotImplementedError

    def reset(self) -> None:
        """Forget integrators and filters (a new run)."""


def bicycle(config: TrackerConfig) -> DynamicBicycleParams:
    """The belief's linear-tyre bicycle (mass, inertia, axle positions and stiffnesses)."""
    model = config.model
    return DynamicBicycleParams.from_vehicle(model, model.cornering_stiffness_front_npr,
                                             model.cornering_stiffness_rear_npr)


def curvature_feedforward(curvature_1pm: float, speed_mps: float,
                          params: DynamicBicycleParams) -> float:
    """``L kappa + K v^2 kappa``: the steady-state steering of a turn of ``kappa``."""
    return (params.wheelbase_m + params.understeer_gradient_radpmps2 * speed_mps**2) \
        * curvature_1pm


class SpeedLoop:
    """PI on the speed error plus the reference's acceleration (``tracker.baseline.speed``)."""

    def __init__(self, config: TrackerConfig) -> None:
        self._cfg = config.baseline.speed
        self._limits = (config.accel_min_mps2, config.accel_max_mps2)
        self._integral = 0.0

    def reset(self) -> None:
        self._integral = 0.0

    def accel(self, pose: Pose, reference: ReferencePath, dt_s: float) -> float:
        s, t, v = pose.projection.s_m, pose.t_s, max(pose.vx_mps, 0.0)
        ahead = ACCEL_FEEDFORWARD_S
        v_ref = reference.speed_ref_at(s, t)
        v_next = reference.speed_ref_at(s + max(v, v_ref) * ahead, t + ahead)
        error = v_ref - pose.vx_mps
        limit = self._cfg.integral_limit_mps
        self._integral = float(np.clip(self._integral + error * dt_s, -limit, limit))
        accel = (v_next - v_ref) / ahead + self._cfg.kp * error + self._cfg.ki * self._integral
        if v_ref <= 0.0 and v_next <= 0.0:  # standstill hold
            accel = min(accel, -STANDSTILL_GAIN_PER_S * max(pose.vx_mps, 0.0))
        return float(np.clip(accel, *self._limits))


class BaselineTracker:
    """A :class:`LateralLaw` with the speed loop, bounds and plan of the module docstring."""

    def __init__(self, config: TrackerConfig, law: LateralLaw) -> None:
        self.config = config
        self.law = law
        self.speed = SpeedLoop(config)
        self.params = bicycle(config)
        self._previous: tuple[float, float] | None = None
        """``(t_s, steer_rad)`` of the last command."""

    def reset(self) -> None:
        self.law.reset()
        self.speed.reset()
        self._previous = None

    def _period_s(self, t_s: float) -> float:
        if self._previous is None or t_s <= self._previous[0]:
            return self.config.dt_s
        return t_s - self._previous[0]

    def pose(self, t_s: float, estimate: Estimate, reference: ReferencePath) -> Pose:
        """The estimate, predicted over the believed delay (module docstring)."""
        x, y, yaw = estimate["x_m"], estimate["y_m"], estimate["yaw_rad"]
        vx = estimate["vx_mps"]
        vy = estimate["vy_mps"] if "vy_mps" in estimate else 0.0
        r = estimate["yaw_rate_radps"] if "yaw_rate_radps" in estimate else 0.0
        tau = self.config.latency_s if self.config.latency_compensation else 0.0
        if tau > 0.0:
            # Constant speed and yaw rate over the delay, body velocity turned to the world.
            heading = yaw + 0.5 * r * tau
            x += (vx * math.cos(heading) - vy * math.sin(heading)) * tau
            y += (vx * math.sin(heading) + vy * math.cos(heading)) * tau
            yaw += r * tau
        return Pose(t_s + tau, x, y, yaw, vx, vy, r, reference.project(x, y))

    def step(self, t_s: float, estimate: Estimate,
             reference: ReferencePath) -> tuple[Command, Plan]:
        began = time.perf_counter()
        cfg = self.config
        dt = self._period_s(t_s)
        previous_steer = self._previous[1] if self._previous is not None else 0.0
        if not np.all(np.isfinite(estimate.mean)):
            command = Command(t_s, cfg.safe_stop_accel_mps2, previous_steer)
            self._previous = (t_s, previous_steer)
            return command, self._plan(t_s, None, command, time.perf_counter() - began,
                                       "non_finite_estimate")
        pose = self.pose(t_s, estimate, reference)
        steer = self.law.steer(pose, reference, dt)
        step = cfg.max_steer_rate_radps * dt
        steer = float(np.clip(steer, previous_steer - step, previous_steer + step))
        steer = float(np.clip(steer, -cfg.max_steer_rad, cfg.max_steer_rad))
        accel = self.speed.accel(pose, reference, dt)
        command = Command(t_s, accel, steer)
        self._previous = (t_s, steer)
        return command, self._plan(t_s, pose, command, time.perf_counter() - began, "ok")

    def _plan(self, t_s: float, pose: Pose | None, command: Command, solve_time_s: float,
              status: str) -> Plan:
        dt = self.config.dt_s
        if pose is None:
            states = np.full((2, len(PLAN_STATES)), np.nan)
        else:
            v = pose.vx_mps
            yaw_rate = v * math.tan(command.steer_rad) / self.params.wheelbase_m
            heading = pose.yaw_rad + 0.5 * yaw_rate * dt
            states = np.array([
                [pose.x_m, pose.y_m, pose.yaw_rad, v],
                [pose.x_m + v * math.cos(heading) * dt, pose.y_m + v * math.sin(heading) * dt,
                 pose.yaw_rad + yaw_rate * dt, v + command.accel_mps2 * dt],
            ])
        return Plan(t_s=t_s, dt_s=dt, state_names=PLAN_STATES, states=states,
                    input_names=PLAN_INPUTS,
                    inputs=np.array([[command.accel_mps2, command.steer_rad]]),
                    cost=float("nan"), solve_time_s=solve_time_s, iterations=0,
                    status=status, success=status == "ok", fallback=status != "ok")
