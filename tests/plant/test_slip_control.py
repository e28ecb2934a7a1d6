"""The car's wheel-slip control (cosim.plant.slip_control): the law by hand, then the
MuJoCo sedan on a wet road with and without it."""

from __future__ import annotations

import dataclasses

import pytest

from cosim.core.initial_state import InitialState
from cosim.core.records import ActuatorCommand
from cosim.core.slip_control_params import SlipControlParams
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant
from cosim.plant.slip_control import SlipLimiter

PARAMS = SlipControlParams(enabled=True)  # slip_max 0.05, cut_gain 20, recovery 2 /s
RADIUS_M = 0.3
RWD = (False, False, True, True)
"""Front-left, front-right, rear-left, rear-right: the rear pair driven."""
DT_S = 0.002


def spins(front_mps: float, rear_mps: float) -> list[float]:
    return [front_mps / RADIUS_M] * 2 + [rear_mps / RADIUS_M] * 2


def test_no_slip_passes_the_torques_unchanged() -> None:
    limiter = SlipLimiter(PARAMS, RADIUS_M, RWD)
    out = limiter.limit(1000.0, 0.0, spins(20.0, 20.4), DT_S)  # 2 % slip
    assert (out.drive_torque_nm, out.brake_torque_nm) == (1000.0, 0.0)


@pytest.mark.parametrize("rear_mps, share", [(21.5, 0.5), (22.0, 0.0), (21.0, 1.0)])
def test_drive_torque_is_cut_by_the_rear_wheels_slip(rear_mps: float, share: float) -> None:
    """Undriven front wheels at 20 m/s are the reference: rear at 21.5 m/s is 7.5 % slip,
    0.025 above slip_max, so 20 x 0.025 = half the torque goes; 10 % takes all of it."""
    out = SlipLimiter(PARAMS, RADIUS_M, RWD).limit(1000.0, 0.0, spins(20.0, rear_mps), DT_S)
    assert out.drive_share == pytest.approx(share)
    assert out.drive_torque_nm == pytest.approx(1000.0 * share)


def test_torque_comes_back_at_the_recovery_rate() -> None:
    limiter = SlipLimiter(PARAMS, RADIUS_M, RWD)
    limiter.limit(1000.0, 0.0, spins(20.0, 22.0), DT_S)  # cut to 0
    shares = [limiter.limit(1000.0, 0.0, spins(20.0, 20.0), DT_S).drive_share
              for _ in range(100)]
    assert shares[0] == pytest.approx(2.0 * DT_S)
    assert shares[-1] == pytest.approx(100 * 2.0 * DT_S)  # 0.4 after 0.2 s


def test_a_locking_wheel_cuts_the_brakes() -> None:
    """Braking: the fastest wheel is the reference; a wheel 7.5 % slower halves the brake
    torque; the drive share is untouched (no drive asked for)."""
    out = SlipLimiter(PARAMS, RADIUS_M, RWD).limit(
        0.0, 2000.0, [20.0 / RADIUS_M, 18.5 / RADIUS_M, 20.0 / RADIUS_M, 20.0 / RADIUS_M],
        DT_S)
    assert out.brake_share == pytest.approx(0.5)
    assert out.brake_torque_nm == pytest.approx(1000.0)
    assert out.drive_share == 1.0


def test_all_wheel_drive_takes_the_slowest_wheel_as_reference() -> None:
    out = SlipLimiter(PARAMS, RADIUS_M, (True,) * 4).limit(
        1000.0, 0.0, spins(20.0, 21.5), DT_S)
    assert out.drive_share == pytest.approx(0.5)


def rear_slip_after_launch(slip_control: bool) -> tuple[float, float]:
    """Largest rear slip ratio over 1 s of full drive torque (2500 N m) from 15 m/s on
    friction 0.5 (the rear axle can carry about 1900 N, 590 N m): over the whole second,
    and over its last half."""
    config = dataclasses.replace(
        PlantConfig(), tyre_friction=0.5,
        slip_control=dataclasses.replace(PARAMS, enabled=slip_control))
    plant = MujocoPlant(config, DT_S, InitialState(speed_mps=15.0))
    plant.apply(ActuatorCommand(t_s=0.0, drive_torque_nm=2500.0, brake_torque_nm=0.0,
                                steer_rad=0.0))
    slips = []
    for _ in range(500):
        plant.advance()
        state = plant.state()
        front = 0.5 * (state.wheel_speed_radps[0] + state.wheel_speed_radps[1])
        rear = 0.5 * (state.wheel_speed_radps[2] + state.wheel_speed_radps[3])
        slips.append((rear - front) / front)
    return max(slips), max(slips[250:])


def test_traction_control_keeps_the_rear_wheels_near_the_target_slip() -> None:
    """Without it the rear wheels spin up (slip far beyond the tyre's peak, about 0.06 at
    this friction). With it the slip stays below ``slip_max + 1 / cut_gain`` (0.1), where
    (L2) leaves no torque at all; once settled it sits above slip_max, the proportional
    law's offset that keeps the quarter of the torque the road can carry."""
    assert rear_slip_after_launch(False)[1] > 0.5
    worst, settled = rear_slip_after_launch(True)
    ceiling = PARAMS.slip_max + 1.0 / PARAMS.cut_gain
    assert worst < ceiling
    assert PARAMS.slip_max < settled < ceiling
