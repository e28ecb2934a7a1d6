"""AccelToTorque: acceleration demand to wheel torque with the controller's belief.

Nominal belief: m = 1575 kg, m_eff = 1575 + 4 * 1 / 0.31^2 = 1616.6 kg, R = 0.31 m,
drag 0.5 * 1.225 * 0.66 v^2 = 0.404 v^2 N, rolling 0.012 * 1575 * 9.81 = 185.4 N,
limits 4000 N m drive, 150 kW, 8000 N m brake.
"""

from __future__ import annotations

import math

import pytest

from cosim.core.records import ActuatorCommand, Command
from cosim.core.vehicle_params import VehicleParams
from cosim.plant.low_level import AccelToTorque, effective_mass_kg

BELIEF = VehicleParams()


def convert(accel_mps2: float, speed_mps: float, steer_rad: float = 0.0) -> ActuatorCommand:
    return AccelToTorque(BELIEF).convert(Command(1.5, accel_mps2, steer_rad), speed_mps)


def test_effective_mass_includes_the_wheels() -> None:
    assert effective_mass_kg(BELIEF) == pytest.approx(1616.6, abs=0.1)


def test_zero_demand_drives_against_drag_and_rolling_resistance() -> None:
    # (161.7 N + 185.4 N) * 0.31 m = 107.6 N m at 20 m/s.
    command = convert(0.0, 20.0)
    assert command.drive_torque_nm == pytest.approx(107.6, abs=0.2)
    assert command.brake_torque_nm == 0.0


def test_acceleration_demand() -> None:
    # (1616.6 * 2 + 40.4 + 185.4) N * 0.31 m = 1072.3 N m at 10 m/s.
    command = convert(2.0, 10.0, steer_rad=0.1)
    assert command.drive_torque_nm == pytest.approx(1072.3, abs=0.5)
    assert command.brake_torque_nm == 0.0
    assert command.steer_rad == 0.1 and command.t_s == 1.5


def test_braking_demand() -> None:
    # (1616.6 * -3 + 91.0 + 185.4) N * 0.31 m = -1417.7 N m at 15 m/s: brake.
    command = convert(-3.0, 15.0)
    assert command.drive_torque_nm == 0.0
    assert command.brake_torque_nm == pytest.approx(1417.7, abs=0.5)


def test_power_limit() -> None:
    # At 30 m/s, 150 kW give 5000 N, i.e. 1550 N m: a 3 m/s^2 demand (1673 N m) is clipped.
    assert convert(3.0, 30.0).drive_torque_nm == pytest.approx(1550.0)


def test_torque_and_brake_limits() -> None:
    assert convert(10.0, 1.0).drive_torque_nm == 4000.0
    assert convert(-50.0, 20.0).brake_torque_nm == 8000.0


def test_a_wrong_belief_gives_a_different_torque() -> None:
    heavier = AccelToTorque(VehicleParams(mass_kg=2000.0)).convert(Command(0, 2.0, 0), 10.0)
    assert heavier.drive_torque_nm > convert(2.0, 10.0).drive_torque_nm * 1.2


@pytest.mark.parametrize(
    "fields",
    [
        {"drive_torque_nm": -1.0},
        {"brake_torque_nm": -1.0},
        {"steer_rad": math.nan},
        {"drive_torque_nm": math.inf},
    ],
)
def test_actuator_command_rejects_bad_values(fields: dict[str, float]) -> None:
    values = {"t_s": 0.0, "drive_torque_nm": 0.0, "brake_torque_nm": 0.0, "steer_rad": 0.0}
    values.update(fields)
    with pytest.raises(ValueError, match=next(iter(fields))):
        ActuatorCommand(**values)


def test_non_finite_speed_is_rejected() -> None:
    with pytest.raises(ValueError, match="speed_mps"):
        convert(1.0, math.nan)
