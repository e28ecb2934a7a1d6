"""A plain-numpy dynamic bicycle with a steering actuator, and a closed loop around a
tracker, for the tests.

The car is integrated independently of the CasADi model in
:mod:`tracker.models.steered_dynamic_bicycle`: with linear tyres the lateral dynamics are
the state-space form ``[vy, r]' = A(vx) [vy, r] + B delta`` (Rajamani 2012, sec. 2.3, a11 ...
b21, from :meth:`tracker.models.dynamic_bicycle.DynamicBicycleParams.lateral_state_space`);
with a ``tyre_friction`` each axle's force ``C alpha`` is held within the friction force of
its static load, ``mu F_z tanh(C alpha / (mu F_z))``, the saturating tyres of
``tracker.grip.saturating_tyres``. The pose is integrated from the body velocities,
``vx' = a``, all by RK4 at the physics step (2 ms).
The steering actuator is the plant's (:mod:`cosim.plant.car`): a first-order lag of the command,
exactly discretised, then a rate limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from cosim.core.records import Command, Estimate, Plan
from tracker.models.dynamic_bicycle import GRAVITY_MPS2, LATERAL_STATE, DynamicBicycleParams
from tracker.paths.reference_path import ReferencePath, wrap_angle

ESTIMATE_NAMES: tuple[str, ...] = ("x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps",
                                   "yaw_rate_radps")


@dataclass(frozen=True)
class Car:
    """State of the bench car: CoG pose (world frame), body velocities, road-wheel angle."""

    x_m: float
    y_m: float
    yaw_rad: float
    vx_mps: float
    vy_mps: float = 0.0
    yaw_rate_radps: float = 0.0
    steer_rad: float = 0.0


@dataclass(frozen=True)
class Actuator:
    """The bench's steering actuator (the plant's model: lag, then rate limit)."""

    time_constant_s: float = 0.05
    max_rate_radps: float = 0.8


def _lateral(vx: float, vy: float, r: float, steer_rad: float,
             params: DynamicBicycleParams, tyre_friction: float | None) -> np.ndarray:
    """``[vy', r']`` with linear tyres (the state-space form) or saturating ones."""
    if tyre_friction is None:
        a, b = params.lateral_state_space(vx)
        return a @ np.array([vy, r]) + b[:, 0] * steer_rad
    l_f, l_r, mass = params.cog_front_m, params.cog_rear_m, params.mass_kg
    weight = mass * GRAVITY_MPS2
    forces = []
    for stiffness, alpha, load in (
            (params.cornering_stiffness_front_npr, steer_rad - (vy + l_f * r) / vx,
             weight * l_r / (l_f + l_r)),
            (params.cornering_stiffness_rear_npr, -(vy - l_r * r) / vx,
             weight * l_f / (l_f + l_r))):
        limit = tyre_friction * load
        forces.append(limit * math.tanh(stiffness * alpha / limit))
    front, rear = forces
    rates = {"vy_mps": (front + rear) / mass - vx * r,
             "yaw_rate_radps": (l_f * front - l_r * rear) / params.yaw_inertia_kgm2}
    return np.array([rates[name] for name in LATERAL_STATE])


def _derivative(car: np.ndarray, accel_mps2: float, steer_rad: float,
                params: DynamicBicycleParams, tyre_friction: float | None) -> np.ndarray:
    """``[x, y, yaw, vx, vy, r]'`` of the dynamic bicycle (Rajamani 2012, sec. 2.3)."""
    _, yaw, vx, vy, r = car[1], car[2], car[3], car[4], car[5]
    lateral = _lateral(vx, vy, r, steer_rad, params, tyre_friction)
    return np.array([
        vx * math.cos(yaw) - vy * math.sin(yaw),
        vx * math.sin(yaw) + vy * math.cos(yaw),
        r,
        accel_mps2,
        lateral[LATERAL_STATE["vy_mps"]],
        lateral[LATERAL_STATE["yaw_rate_radps"]],
    ])


def advance(car: Car, command: Command, dt_s: float, params: DynamicBicycleParams,
            actuator: Actuator, tyre_friction: float | None = None) -> Car:
    """One physics step: the actuator, then RK4 of the car at the new road-wheel angle."""
    tau = actuator.time_constant_s
    decay = math.exp(-dt_s / tau) if tau > 0.0 else 0.0
    lagged = command.steer_rad + (car.steer_rad - command.steer_rad) * decay
    step_max = actuator.max_rate_radps * dt_s
    steer = car.steer_rad + float(np.clip(lagged - car.steer_rad, -step_max, step_max))
    x = np.array([car.x_m, car.y_m, car.yaw_rad, car.vx_mps, car.vy_mps, car.yaw_rate_radps])
    k1 = _derivative(x, command.accel_mps2, steer, params, tyre_friction)
    k2 = _derivative(x + 0.5 * dt_s * k1, command.accel_mps2, steer, params, tyre_friction)
    k3 = _derivative(x + 0.5 * dt_s * k2, command.accel_mps2, steer, params, tyre_friction)
    k4 = _derivative(x + dt_s * k3, command.accel_mps2, steer, params, tyre_friction)
    x = x + dt_s / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return Car(*(float(v) for v in x), steer_rad=steer)


def estimate_of(t_s: float, car: Car) -> Estimate:
    """A perfect estimate of the car (no steering angle: no estimator reports one)."""
    car = replace(car, yaw_rad=float(wrap_angle(car.yaw_rad)))
    mean = np.array([getattr(car, name) for name in ESTIMATE_NAMES])
    return Estimate(t_s=t_s, names=ESTIMATE_NAMES, mean=mean,
                    covariance=np.eye(len(ESTIMATE_NAMES)) * 1e-4)


@dataclass
class ClosedLoopResult:
    """Everything a closed-loop run produced."""

    cte_m: np.ndarray
    """Signed cross-track error of the CoG at every physics step."""
    vx_mps: np.ndarray
    steer_rad: np.ndarray
    """Road-wheel angle at every physics step."""
    commands: list[Command]
    plans: list[Plan]
    estimates: list[Estimate]
    final: Car


def run_closed_loop(tracker: object, reference: ReferencePath, initial: Car,
                    duration_s: float, params: DynamicBicycleParams,
                    actuator: Actuator = Actuator(), physics_dt_s: float = 0.002,
                    control_period_s: float = 0.05,
                    tyre_friction: float | None = None) -> ClosedLoopResult:
    """Drive the bench car with ``tracker.step`` every control period (its tyres saturate
    at ``tyre_friction`` when one is given)."""
    steps_per_control = int(round(control_period_s / physics_dt_s))
    car = initial
    ctes, speeds, steers = [], [], []
    commands, plans, estimates = [], [], []
    for i in range(int(round(duration_s / control_period_s))):
        t_s = i * control_period_s
        estimate = estimate_of(t_s, car)
        command, plan = tracker.step(t_s, estimate, reference)  # type: ignore[attr-defined]
        estimates.append(estimate)
        commands.append(command)
        plans.append(plan)
        for _ in range(steps_per_control):
            car = advance(car, command, physics_dt_s, params, actuator, tyre_friction)
            ctes.append(reference.project(car.x_m, car.y_m).lateral_error_m)
            speeds.append(car.vx_mps)
            steers.append(car.steer_rad)
    return ClosedLoopResult(np.array(ctes), np.array(speeds), np.array(steers), commands,
                            plans, estimates, car)
