"""The road wheels' gyroscopic deflection in the filter's steering ((S4) of
estimation.steering_model): by hand, against the plant's servo, and along a lane change."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from cosim.core.vehicle_params import VehicleParams
from cosim.log.reader import iter_messages
from cosim.log.topics import VEHICLE_ESTIMATE, VEHICLE_TRUTH
from cosim.plant.sedan_model import sedan_layout
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from estimation.belief_models import bicycle_params, process_noise
from estimation.config import EstimatorConfig
from estimation.process_model import ProcessModel
from estimation.state import state_index
from estimation.steering_model import SteeringBelief, gyro_deflection, steering_derivatives
from tests.estimation.test_models import _state

STEER, STEER_RATE = state_index("steer_rad"), state_index("steer_rate_radps")
ROLL_RATE = state_index("roll_rate_radps")


def test_the_default_compliance_is_the_sedans_steering_servo() -> None:
    """Not fitted: one over the gain of the plant's steering servo, and with the belief's
    wheel spin inertia the deflection per spin rate times roll rate is the plant's
    ``I_s / k``."""
    plant = load_config("lane-change").plant
    layout = sedan_layout(plant)
    compliance = EstimatorConfig().steering_compliance_radpnm
    assert compliance == pytest.approx(1.0 / layout.steer_servo_kp_nmprad, rel=1e-6)
    steering = SteeringBelief.from_vehicle(VehicleParams(), compliance)
    assert steering.gyro_deflection_s2 == pytest.approx(
        layout.wheel_inertia_kgm2[1] / layout.steer_servo_kp_nmprad, rel=1e-6)


def test_the_lag_acts_on_the_actuators_angle_and_the_wheels_lag_it() -> None:
    """(S4) by hand: with a command, the lag pulls the actuator's angle ``delta + D`` and the
    road wheels move at the actuator's rate less ``D'``; without one, nothing changes."""
    steering = SteeringBelief(gyro_deflection_s2=1.75e-4, wheel_radius_m=0.31)
    deflection = gyro_deflection(20.0, 0.12, steering)
    assert float(deflection) == pytest.approx(1.75e-4 * 20.0 / 0.31 * 0.12, rel=1e-12)
    commanded, untold = np.array([0.05, 1.0]), np.array([0.0, 0.0])
    for command in (commanded, untold):
        moved = [float(v) for v in steering_derivatives(0.02, 0.1, command, steering,
                                                        deflection, 0.004)]
        rigid = [float(v) for v in steering_derivatives(0.02 + float(deflection), 0.1,
                                                        command, steering)]
        shift = 0.004 if command[1] else 0.0
        assert moved == pytest.approx([rigid[0] - shift, rigid[1]], rel=1e-12, abs=1e-15)


def test_the_process_model_turns_the_roll_into_the_wheels_lag() -> None:
    """The process model's steering derivative with the deflection: the rigid one at the
    actuator's angle, less ``D' = c (v_x' p + v_x p') / R`` with the model's own roll
    acceleration; the rate state relaxes to the actuator's lag rate; the other states'
    derivatives are untouched."""
    belief = VehicleParams()
    noise = process_noise(EstimatorConfig())
    bicycle = bicycle_params(EstimatorConfig(), belief)
    c = 1.0 / 5700.417 * belief.wheel_inertia_kgm2
    flexible = ProcessModel(noise, bicycle, 0.5, steering=SteeringBelief.from_vehicle(
        belief, 1.0 / 5700.417))
    rigid = ProcessModel(noise, bicycle, 0.5, steering=SteeringBelief.from_vehicle(belief))
    x = _state(vx_mps=20.0, vy_mps=0.1, yaw_rate_radps=0.2, ax_mps2=0.5, steer_rad=0.03,
               steer_rate_radps=0.05, roll_rad=0.02, roll_rate_radps=0.1)
    moved = flexible.derivative(x, 0.04)[0]
    still = rigid.derivative(x, 0.04)[0]
    roll_accel = still[ROLL_RATE]
    vx_change = 0.5 + 0.2 * 0.1
    rate = c / belief.wheel_radius_m * (vx_change * 0.1 + 20.0 * roll_accel)
    deflection = c * 20.0 / belief.wheel_radius_m * 0.1
    x_actuator = x.copy()
    x_actuator[STEER] += deflection
    lagged = rigid.derivative(x_actuator, 0.04)[0]
    assert moved[STEER] == pytest.approx(lagged[STEER] - rate, rel=1e-9)
    assert moved[STEER_RATE] == pytest.approx(lagged[STEER_RATE], rel=1e-12)
    others = ~np.isin(np.arange(len(x)), (STEER, STEER_RATE))
    np.testing.assert_array_equal(moved[others], still[others])


def _steering_error(path: Path) -> float:
    truth = {round(m["t_s"], 4): m["steer_rad"] for _, m in iter_messages(path, VEHICLE_TRUTH)}
    errors = [m["steer_rad"] - truth[round(m["t_s"], 4)]
              for _, m in iter_messages(path, VEHICLE_ESTIMATE)
              if m["t_s"] >= 1.0 and round(m["t_s"], 4) in truth]
    return float(np.sqrt(np.mean(np.square(errors))))


@pytest.mark.slow
def test_along_a_lane_change_the_steering_follows_the_road_wheels(tmp_path: Path) -> None:
    """The default lane change (rtk, seed 8722): the filter's steering against the true
    road-wheel angle, after the first second, with the sedan's compliance, none, and three
    times it."""
    config = load_config("lane-change", overrides=["sensors.suite=rtk"], seed=8722)
    errors = {}
    for scale in (1.0, 0.0, 3.0):
        estimator = dataclasses.replace(
            config.estimator,
            steering_compliance_radpnm=scale * config.estimator.steering_compliance_radpnm)
        path = tmp_path / f"{scale}.mcap"
        run(dataclasses.replace(config, estimator=estimator), path)
        errors[scale] = _steering_error(path)
    assert errors[1.0] < 0.6 * errors[0.0], errors
    assert errors[1.0] < 0.6 * errors[3.0], errors
