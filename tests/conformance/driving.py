"""Drive the plant directly for the conformance tests: speed loop, steering profile, fits.

Nominal car (The MathWorks' lane-keeping MPC example): m = 1575 kg, l_f = 1.2 m, l_r = 1.6 m, L =
2.8 m.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cosim.core.initial_state import InitialState
from cosim.core.records import ActuatorCommand, Command, VehicleState
from cosim.core.vehicle_params import PlantConfig, VehicleParams
from cosim.plant.car import MujocoPlant
from cosim.plant.low_level import AccelToTorque

DT_S = 0.002
"""Physics step [s], the runner's default."""

CONTROL_STEPS = 25
"""Commands are applied every 25 physics steps (50 ms), as the runner's control period."""

GRAVITY_MPS2 = 9.81

WHEELBASE_M = 2.8
COG_REAR_M = 1.6

Controller = Callable[[VehicleState], ActuatorCommand]


def plant_at(speed_mps: float, config: PlantConfig) -> MujocoPlant:
    """The plant at the origin heading east at ``speed_mps``."""
    return MujocoPlant(config, DT_S, InitialState(speed_mps=speed_mps))


def drive(plant: MujocoPlant, duration_s: float, controller: Controller | None = None,
          stop: Callable[[VehicleState], bool] | None = None) -> list[VehicleState]:
    """Advance ``duration_s`` (or until ``stop(state)``); the state after every step.

    ``controller(state)`` is applied every :data:`CONTROL_STEPS` steps.
    """
    states = []
    for k in range(round(duration_s / DT_S)):
        if controller is not None and k % CONTROL_STEPS == 0:
            plant.apply(controller(plant.state()))
        plant.advance()
        state = plant.state()
        states.append(state)
        if stop is not None and stop(state):
            break
    return states


def speed_loop(belief: VehicleParams, speed_mps: float, steer_rad: Callable[[float], float],
               gain_per_s: float = 2.0) -> Controller:
    """Hold ``speed_mps`` (acceleration demand ``gain (v_ref - v)`` through
    :class:`AccelToTorque`) while steering ``steer_rad(t)`` (bicycle-model angle)."""
    low_level = AccelToTorque(belief)

    def command(state: VehicleState) -> ActuatorCommand:
        accel = gain_per_s * (speed_mps - state.vx_mps)
        return low_level.convert(Command(state.t_s, accel, steer_rad(state.t_s)), state.vx_mps)

    return command


def constant_accel(belief: VehicleParams, accel_mps2: float) -> Controller:
    """Demand ``accel_mps2`` through :class:`AccelToTorque` with ``belief``, steering 0."""
    low_level = AccelToTorque(belief)

    def command(state: VehicleState) -> ActuatorCommand:
        return low_level.convert(Command(state.t_s, accel_mps2, 0.0), state.vx_mps)

    return command


def rear_axle_xy(state: VehicleState) -> tuple[float, float]:
    """World position of the rear-axle centre, l_r behind the CoG along the heading."""
    return (state.x_m - COG_REAR_M * math.cos(state.yaw_rad),
            state.y_m - COG_REAR_M * math.sin(state.yaw_rad))


def circle_radius_m(points: np.ndarray) -> float:
    """Radius of the least-squares circle through ``points`` (N x 2), the algebraic fit
    ``x^2 + y^2 + D x + E y + F = 0`` (Kasa 1976)."""
    x, y = points[:, 0], points[:, 1]
    design = np.column_stack([x, y, np.ones_like(x)])
    (d, e, f), *_ = np.linalg.lstsq(design, -(x * x + y * y), rcond=None)
    return float(math.sqrt(d * d / 4.0 + e * e / 4.0 - f))


def low_pass(values: list[float], time_constant_s: float) -> list[float]:
    """First-order low-pass filter of a signal sampled every :data:`DT_S`."""
    out, y = [], values[0]
    weight = 1.0 - math.exp(-DT_S / time_constant_s)
    for value in values:
        y += weight * (value - y)
        out.append(y)
    return out
