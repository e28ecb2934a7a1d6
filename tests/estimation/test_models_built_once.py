"""A filter's CasADi models are built once per process and shared by every filter with the
same numbers; each filter evaluates them through buffers of its own."""

from __future__ import annotations

import dataclasses

import numpy as np

from cosim.core.initial_state import InitialState
from cosim.simulation.scenario_config import load_config
from estimation.config import EstimatorConfig
from estimation.ekf import Ekf


def _filters(first: EstimatorConfig, second: EstimatorConfig) -> tuple[Ekf, Ekf]:
    belief = load_config("lane-change").tracker.model
    initial = InitialState(x_m=0.0, y_m=0.0, yaw_rad=0.0, speed_mps=20.0)
    return (Ekf(first, initial, belief, rng=np.random.default_rng(1)),
            Ekf(second, initial, belief, rng=np.random.default_rng(1)))


def test_equal_filters_share_their_functions_not_their_evaluators() -> None:
    config = EstimatorConfig(name="ekf")
    a, b = _filters(config, config)
    assert a._process.step_function is b._process.step_function
    assert a._models["imu"].function.function is b._models["imu"].function.function
    assert a._joint_function.function.function is b._joint_function.function.function
    assert a._process._step_fast is not b._process._step_fast
    assert a._models["imu"].function is not b._models["imu"].function
    # Interleaved, each gives what it gives alone.
    state = np.linspace(0.1, 1.7, 17)  # any finite state will do
    alone = a._process.step(state, 0.01)
    b._process.step(2.0 * state, 0.01)
    again = a._process.step(state, 0.01)
    assert all(np.array_equal(u, v) for u, v in zip(alone, again, strict=True))


def test_other_numbers_get_functions_of_their_own_belief() -> None:
    config = EstimatorConfig(name="ekf")
    other = dataclasses.replace(config, yaw_accel_psd_rad2ps3=3.0 * config.yaw_accel_psd_rad2ps3)
    a, b = _filters(config, other)
    assert not np.array_equal(a._process.belief_values, b._process.belief_values)
    state = np.linspace(0.1, 1.7, 17)
    assert not np.array_equal(a._process.step(state, 0.01)[2], b._process.step(state, 0.01)[2])
