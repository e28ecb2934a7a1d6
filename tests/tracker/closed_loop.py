"""A plain-numpy kinematic bicycle and a closed loop around a tracker, for the tests.

The car is integrated independently of the CasADi model in :mod:`tracker.models.kinematic_bicycle`
(same equations, Rajamani 2012 sec. 2.2 at the centre of gravity, fine RK4 at the physics
step), so the tests compare the controller's model against a plain reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosim.core.records import Command, Estimate, Plan
from cosim.core.vehicle_params import VehicleParams
from tracker.paths.reference_path import ReferencePath, wrap_angle

ESTIMATE_NAMES: tuple[str, ...] = ("x_m", "y_m", "yaw_rad", "vx_mps")


@dataclass
class CarState:
    """Kinematic bicycle state at the centre of gravity (world frame)."""

    x_m: float
    y_m: float
    yaw_rad: float
    speed_mps: float


def derivative(state: CarState, accel_mps2: float, steer_rad: float,
               params: VehicleParams) -> CarState:
    """Time derivative of each field of the kinematic bicycle at the CoG, eqs. K1-K5."""
    beta = np.arctan(params.cog_rear_m / params.wheelbase_m * np.tan(steer_rad))
    return CarState(
        x_m=state.speed_mps * np.cos(state.yaw_rad + beta),
        y_m=state.speed_mps * np.sin(state.yaw_rad + beta),
        yaw_rad=state.speed_mps * np.cos(beta) * np.tan(steer_rad) / params.wheelbase_m,
        speed_mps=accel_mps2,
    )


def _advance(state: CarState, h: float, rate: CarState) -> CarState:
    """``state + h * rate``, field by field."""
    return CarState(state.x_m + h * rate.x_m, state.y_m + h * rate.y_m,
                    state.yaw_rad + h * rate.yaw_rad, state.speed_mps + h * rate.speed_mps)


def rk4(state: CarState, accel_mps2: float, steer_rad: float, dt_s: float,
        params: VehicleParams) -> CarState:
    """One classical RK4 step of the plain-numpy car."""
    k1 = derivative(state, accel_mps2, steer_rad, params)
    k2 = derivative(_advance(state, dt_s / 2, k1), accel_mps2, steer_rad, params)
    k3 = derivative(_advance(state, dt_s / 2, k2), accel_mps2, steer_rad, params)
    k4 = derivative(_advance(state, dt_s, k3), accel_mps2, steer_rad, params)
    state = _advance(state, dt_s / 6.0, k1)
    state = _advance(state, dt_s / 3.0, k2)
    state = _advance(state, dt_s / 3.0, k3)
    return _advance(state, dt_s / 6.0, k4)


def estimate_of(t_s: float, state: CarState) -> Estimate:
    """A perfect estimate of the car, yaw wrapped to (-pi, pi] as an estimator reports it."""
    mean = np.array([state.x_m, state.y_m, float(wrap_angle(state.yaw_rad)), state.speed_mps])
    return Estimate(t_s=t_s, names=ESTIMATE_NAMES, mean=mean, covariance=np.eye(4) * 1e-4)


@dataclass
class ClosedLoopResult:
    """Everything a closed-loop run produced."""

    cte_m: np.ndarray
    """Signed cross-track error of the CoG at every physics step."""
    speed_mps: np.ndarray
    """Speed at every physics step."""
    commands: list[Command]
    plans: list[Plan]
    estimates: list[Estimate]
    final: CarState


def run_closed_loop(
    tracker: object,
    reference: ReferencePath,
    initial: CarState,
    duration_s: float,
    params: VehicleParams,
    physics_dt_s: float = 0.002,
    control_period_s: float = 0.05,
) -> ClosedLoopResult:
    """Drive the plain-numpy car with ``tracker.step`` every control period."""
    steps_per_control = int(round(control_period_s / physics_dt_s))
    n_controls = int(round(duration_s / control_period_s))
    state = initial
    ctes, speeds = [], []
    commands, plans, estimates = [], [], []
    for i in range(n_controls):
        t_s = i * control_period_s
        estimate = estimate_of(t_s, state)
        command, plan = tracker.step(t_s, estimate, reference)  # type: ignore[attr-defined]
        estimates.append(estimate)
        commands.append(command)
        plans.append(plan)
        for _ in range(steps_per_control):
            state = rk4(state, command.accel_mps2, command.steer_rad, physics_dt_s, params)
            ctes.append(reference.project(state.x_m, state.y_m).lateral_error_m)
            speeds.append(state.speed_mps)
    return ClosedLoopResult(np.array(ctes), np.array(speeds), commands, plans, estimates, state)
