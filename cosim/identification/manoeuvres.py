"""Scripted manoeuvres of the MuJoCo plant for system identification.

The plant is driven directly (no runner, no sensors, no estimator): every physics step a
script sets a :class:`~cosim.core.records.Command`; it passes the plant's transport delay
(``actuator_delay_s``, in whole physics steps, as in the runner) and
:class:`~cosim.plant.low_level.AccelToTorque` with the controller's belief, and the plant
advances one step. Measurements are the true :class:`~cosim.core.records.VehicleState`.

Where the speed must be held (steady turns, step steers, steering steps), a PI loop on the
forward speed sets ``accel_mps2``. The manoeuvres follow the test practice of ISO 4138
(steady-state circular driving) and ISO 7401 (step steer), reduced to what the fits need.
"""

from __future__ import annotations

import collections
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cosim.core.initial_state import InitialState
from cosim.core.records import Command, VehicleState
from cosim.core.vehicle_params import PlantConfig, VehicleParams
from cosim.identification.data import (
    IdentificationError,
    LateralResponse,
    SteadyTurn,
    StepResponse,
)
from cosim.plant.car import MujocoPlant
from cosim.plant.low_level import AccelToTorque
from cosim.simulation.scenario_config import steps_per_period

SPEED_GAIN_PER_S = 1.5
"""Proportional gain of the speed loop: accel demand per m/s of speed error [1/s]."""

SPEED_INTEGRAL_GAIN_PER_S2 = 0.8
"""Integral gain of the speed loop [1/s^2]."""

STEADY_YAW_RATE_SPREAD = 0.03
"""A turn is steady when the yaw rate over the averaging window stays within this share of
its mean (peak to peak)."""

STEADY_SPEED_TOLERANCE = 0.02
"""... and its speed within this share of the target speed."""


@dataclass(frozen=True)
class Rig:
    """How the plant is built and commanded: true config, controller belief, time step."""

    plant: PlantConfig
    belief: VehicleParams
    physics_dt_s: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.physics_dt_s) and self.physics_dt_s > 0.0):
            raise IdentificationError(
                f"physics_dt_s = {self.physics_dt_s!r}: expected a positive time step")
        steps_per_period(self.plant.actuator_delay_s, self.physics_dt_s,
                         "plant.actuator_delay_s")

    def steps(self, duration_s: float) -> int:
        """Whole physics steps in ``duration_s`` (rounded to the nearest)."""
        return max(1, round(duration_s / self.physics_dt_s))


Script = Callable[[int, VehicleState], tuple[float, float]]
"""``(step, state) -> (accel_mps2, steer_rad)``: the command of one physics step."""


def drive(rig: Rig, speed_mps: float, steps: int, script: Script) -> tuple[
        list[VehicleState], list[Command]]:
    """Run a fresh plant from a straight run at ``speed_mps`` for ``steps`` physics steps.

    Returns the state at every step (before the step's command acts, ``steps + 1`` of them)
    and the command given at every step (before the transport delay). Every script starts
    from straight running with no acceleration demand, which is also what the delay line
    holds at the start.
    """
    plant = MujocoPlant(rig.plant, rig.physics_dt_s, InitialState(speed_mps=speed_mps))
    low_level = AccelToTorque(rig.belief)
    delay_steps = steps_per_period(rig.plant.actuator_delay_s, rig.physics_dt_s,
                                   "plant.actuator_delay_s")
    # The car has been running straight before: the transport delay holds neutral
    # commands (no steering, no acceleration demand), not nothing.
    line = collections.deque(Command(-(i + 1) * rig.physics_dt_s, 0.0, 0.0)
                             for i in reversed(range(delay_steps)))
    states = [plant.state()]
    commands = []
    for k in range(steps):
        state = states[-1]
        accel, steer = script(k, state)
        command = Command(state.t_s, accel, steer)
        commands.append(command)
        line.append(command)
        if len(line) > delay_steps:
            plant.apply(low_level.convert(line.popleft(), state.vx_mps))
        plant.advance()
        states.append(plant.state())
    return states, commands


class SpeedHold:
    """PI loop on the forward speed, stepped once per physics step of ``dt_s``."""

    def __init__(self, speed_mps: float, dt_s: float) -> None:
        self.speed_mps = speed_mps
        self.dt_s = dt_s
        self._integral_mps_s = 0.0

    def accel_mps2(self, state: VehicleState) -> float:
        error = self.speed_mps - state.vx_mps
        self._integral_mps_s += error * self.dt_s
        return SPEED_GAIN_PER_S * error + SPEED_INTEGRAL_GAIN_PER_S2 * self._integral_mps_s


def _hold_speed_and_steer(rig: Rig, speed_mps: float,
                          steer: Callable[[int], float]) -> Script:
    hold = SpeedHold(speed_mps, rig.physics_dt_s)

    def script(k: int, state: VehicleState) -> tuple[float, float]:
        return hold.accel_mps2(state), steer(k)

    return script


def steady_turn(rig: Rig, speed_mps: float, steer_rad: float, settle_s: float = 3.0,
                window_s: float = 1.0) -> SteadyTurn:
    """Constant steering at a held speed; means over the last ``window_s`` of the run.

    Raises :class:`IdentificationError` if the turn is not steady (the car slides or the
    speed loop cannot hold the speed), naming the speed and the steering angle.
    """
    total = rig.steps(settle_s + window_s)
    states, _ = drive(rig, speed_mps, total, _hold_speed_and_steer(rig, speed_mps,
                                                                   lambda k: steer_rad))
    window = states[-rig.steps(window_s):]
    yaw_rate = np.array([s.yaw_rate_radps for s in window])
    vx = np.array([s.vx_mps for s in window])
    mean_yaw_rate = float(np.mean(yaw_rate))
    spread = float(np.ptp(yaw_rate))
    if not (spread <= STEADY_YAW_RATE_SPREAD * abs(mean_yaw_rate)
            and np.max(np.abs(vx - speed_mps)) <= STEADY_SPEED_TOLERANCE * speed_mps):
        raise IdentificationError(
            f"steady turn at {speed_mps:g} m/s with {steer_rad:.4g} rad of steering is not "
            f"steady (yaw rate {mean_yaw_rate:.4g} rad/s +- {0.5 * spread:.2g}, speed "
            f"{float(np.min(vx)):.3g}-{float(np.max(vx)):.3g} m/s): expected a car within "
            "its grip"
        )
    return SteadyTurn(
        vx_mps=float(np.mean(vx)),
        vy_mps=float(np.mean([s.vy_mps for s in window])),
        yaw_rate_radps=mean_yaw_rate,
        ay_mps2=float(np.mean([s.ay_mps2 for s in window])),
        steer_rad=float(np.mean([s.steer_rad for s in window])),
    )


def step_steer(rig: Rig, speed_mps: float, steer_rad: float, lead_s: float = 0.2,
               duration_s: float = 2.5, sample_period_s: float = 0.01) -> LateralResponse:
    """A steering step from straight running at a held speed, sampled from the step on
    every ``sample_period_s`` rounded to whole physics steps."""
    lead = rig.steps(lead_s)
    every = rig.steps(sample_period_s)
    states, _ = drive(rig, speed_mps, lead + rig.steps(duration_s),
                      _hold_speed_and_steer(rig, speed_mps,
                                            lambda k: steer_rad if k >= lead else 0.0))
    sampled = states[lead::every]
    return LateralResponse(
        dt_s=every * rig.physics_dt_s,
        steer_rad=np.array([s.steer_rad for s in sampled]),
        vx_mps=np.array([s.vx_mps for s in sampled]),
        vy_mps=np.array([s.vy_mps for s in sampled]),
        yaw_rate_radps=np.array([s.yaw_rate_radps for s in sampled]),
    )


def steering_step(rig: Rig, speed_mps: float, steer_rad: float, lead_s: float = 0.1,
                  duration_s: float = 1.5) -> StepResponse:
    """Commanded against measured road-wheel angle on a steering step at a held speed,
    every physics step."""
    lead = rig.steps(lead_s)
    states, commands = drive(rig, speed_mps, lead + rig.steps(duration_s),
                             _hold_speed_and_steer(rig, speed_mps,
                                                   lambda k: steer_rad if k >= lead else 0.0))
    return StepResponse(
        dt_s=rig.physics_dt_s,
        command=np.array([c.steer_rad for c in commands] + [commands[-1].steer_rad]),
        response=np.array([s.steer_rad for s in states]),
    )


def accel_steps(rig: Rig, speed_mps: float, accel_mps2: tuple[float, ...],
                lead_s: float = 0.2, hold_s: float = 1.5) -> StepResponse:
    """Commanded ``accel_mps2`` against measured ``ax_mps2`` on straight running: zero for
    ``lead_s``, then each demand of ``accel_mps2`` in turn for ``hold_s`` (no speed loop)."""
    lead, hold = rig.steps(lead_s), rig.steps(hold_s)

    def script(k: int, state: VehicleState) -> tuple[float, float]:
        del state
        return (0.0 if k < lead else accel_mps2[min((k - lead) // hold, len(accel_mps2) - 1)],
                0.0)

    states, commands = drive(rig, speed_mps, lead + hold * len(accel_mps2), script)
    return StepResponse(
        dt_s=rig.physics_dt_s,
        command=np.array([c.accel_mps2 for c in commands] + [commands[-1].accel_mps2]),
        response=np.array([s.ax_mps2 for s in states]),
    )
