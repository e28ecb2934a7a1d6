"""The filter's tyres follow the load the longitudinal acceleration moves between the axles
((D3'') of :mod:`estimation.bicycle`): along the true motion of the MuJoCo sedan on the
circuit, the error of the model's yaw acceleration no longer grows with ``a_x a_y``.

The plant's tyres are the Magic Formula's, whose cornering stiffness grows with the wheel's
load; the filter's bicycle is told only how fast (``estimator.tyre_load_sensitivity_*``). The
model is evaluated on the true states of a logged run, so what is measured is the model's
own error, not the filter's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosim.log.reader import iter_messages
from cosim.log.topics import VEHICLE_TRUTH
from cosim.plant.tyre_model import cornering_stiffness_load_elasticity
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from estimation.belief_models import process_noise, roll_params
from estimation.bicycle import BicycleParams
from estimation.config import EstimatorConfig
from estimation.process_model import ProcessModel
from estimation.state import STATE_NAMES, state_index

TRUE_STATES = ("x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "yaw_rate_radps", "ax_mps2",
               "steer_rad", "roll_rad")
"""The filter's states that the truth carries by the same name."""


@pytest.fixture(scope="module")
def ring_truth(tmp_path_factory: pytest.TempPathFactory) -> list[dict]:
    """20 s of the circuit (turns at 4-6 m/s^2, taken accelerating and braking), seed 8710:
    the true state at the log rate."""
    config = load_config("track", seed=8710, duration_s=20.0)
    path = tmp_path_factory.mktemp("ring") / "ring.mcap"
    run(config, Path(path))
    return [message for _, message in iter_messages(path, VEHICLE_TRUTH)]


def _yaw_accel_error_slope(truth: list[dict], load_sensitivity: tuple[float, float],
                           lateral_transfer: bool = False, on: str = "ax_ay") -> float:
    """Least-squares slope of (true yaw acceleration - model's) on ``a_x a_y`` (``on``:
    ``"ay"``, on ``a_y``) [rad/s^2 per (m/s^2)^2, per m/s^2], the model evaluated at each
    true state; ``lateral_transfer``: with (D3'''') and (D5')."""
    config = load_config("track")
    belief, estimator = config.tracker.model, config.estimator
    model = ProcessModel(
        process_noise(estimator),
        BicycleParams.from_vehicle(belief, estimator.tyre_model, roll_params(estimator, belief),
                                   load_sensitivity, lateral_transfer=lateral_transfer),
        estimator.lateral_residual_time_constant_s)
    time_s = np.array([m["t_s"] for m in truth])
    roll_rate = np.gradient(np.array([m["roll_rad"] for m in truth]), time_s)
    yaw_accel = np.gradient(np.array([m["yaw_rate_radps"] for m in truth]), time_s)
    errors, products = [], []
    for i, message in enumerate(truth):
        if message["t_s"] < 1.0:
            continue
        x = np.zeros(len(STATE_NAMES))
        for name in TRUE_STATES:
            x[state_index(name)] = message[name]
        x[state_index("roll_rate_radps")] = roll_rate[i]
        x[state_index("rolling_radius_scale")] = 1.0
        x[state_index("wheel_track_scale")] = 1.0
        derivative, _ = model.derivative(x)
        errors.append(yaw_accel[i] - derivative[state_index("yaw_rate_radps")])
        products.append(message["ay_mps2"] if on == "ay"
                        else message["ax_mps2"] * message["ay_mps2"])
    products_arr, errors_arr = np.array(products), np.array(errors)
    design = np.column_stack([products_arr, np.ones_like(products_arr)])
    return float(np.linalg.lstsq(design, errors_arr, rcond=None)[0][0])


@pytest.mark.slow
def test_the_axles_balance_follows_the_load_transfer(ring_truth: list[dict]) -> None:
    static = _yaw_accel_error_slope(ring_truth, (0.0, 0.0))
    transferred = _yaw_accel_error_slope(ring_truth,
                                         load_config("track").estimator.tyre_load_sensitivities)
    print(f"yaw acceleration error per a_x a_y: static loads {static:.4f}, "
          f"transferred {transferred:.4f} rad/s^2 per (m/s^2)^2")
    # Static loads: accelerating out of a 5 m/s^2 turn at 1 m/s^2 the model turns the car
    # some 0.1 rad/s^2 harder than it turns.
    assert static < -0.01
    # With the transfer, a quarter of that at most (the transfer's sign reversed doubles it;
    # exponents of 1, as for a stiffness proportional to the load, overshoot to the other
    # side by half of it).
    assert abs(transferred) < 0.25 * abs(static)


def test_the_default_exponents_are_the_sedans_tyres() -> None:
    """The defaults are not fitted: they are the elasticity of the plant's Magic Formula
    cornering stiffness (4.E25) in the load, at the sedan's static front and rear wheel
    loads, to the two digits the configuration states."""
    config = load_config("lane-change")
    plant = config.plant
    expected = tuple(cornering_stiffness_load_elasticity(plant.tyre, load)
                     for load in plant.static_wheel_loads_n)
    np.testing.assert_allclose(EstimatorConfig().tyre_load_sensitivities, expected, atol=0.005)


@pytest.mark.slow
def test_the_front_wheels_turn_the_car_less_as_the_load_moves_out(
        ring_truth: list[dict]) -> None:
    """In a turn the roll moment ``m h a_y`` moves load to the outer wheels, whose tyres then
    carry more of the axle's force; steered, the front pair's forces point unequally along
    the car, a yaw moment ``t_f / 2 sin(delta) (F_yl - F_yr)`` against the turn that the
    bicycle's axles do not have ((D3'''') and (D5') of :mod:`estimation.bicycle`). Along the
    sedan's true motion on the circuit, the model's yaw acceleration without them is off in
    proportion to ``a_y``; with them, far less."""
    sensitivity = load_config("track").estimator.tyre_load_sensitivities
    axles = _yaw_accel_error_slope(ring_truth, sensitivity, on="ay")
    wheels = _yaw_accel_error_slope(ring_truth, sensitivity, lateral_transfer=True, on="ay")
    print(f"yaw acceleration error per a_y: the axles' loads {axles:.5f}, "
          f"the wheels' {wheels:.5f} rad/s^2 per m/s^2")
    # The axles alone: the model turns the car faster than it turns, by some 0.004 rad/s^2
    # per m/s^2 (0.02 rad/s^2 in the circuit's turns); with the front wheels' moment, a seventh
    # of that (the moment's sign reversed doubles it, -0.009; each wheel's law at its load in the
    # axles' forces as well turns it over to 0.6 of it the other way).
    assert axles < -0.002
    assert abs(wheels) < 0.2 * abs(axles)
