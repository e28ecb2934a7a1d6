"""The shared NMPC machinery: what it demands of a model, and that both trackers are one
NLP on two models."""

from __future__ import annotations

import dataclasses

import casadi as ca
import pytest

from cosim.core.config_fields import from_dict
from cosim.core.exceptions import ConfigError
from tracker.config import TrackerConfig
from tracker.mpc.dynamic_nmpc import DynamicNmpc, dynamic_model
from tracker.mpc.kinematic_nmpc import KinematicNmpc, kinematic_model
from tracker.mpc.nmpc import INPUT_NAMES, Nmpc, NmpcModel

CONFIG = from_dict(TrackerConfig, {})


def test_both_trackers_are_the_shared_nmpc_on_a_model() -> None:
    kinematic = KinematicNmpc(dataclasses.replace(CONFIG, name="kinematic-nmpc"))
    dynamic = DynamicNmpc(CONFIG)
    assert isinstance(kinematic, Nmpc) and isinstance(dynamic, Nmpc)
    assert kinematic.state_names == ("x_m", "y_m", "yaw_rad", "vx_mps")
    assert dynamic.state_names[-1] == "road_wheel_angle_rad"
    assert kinematic.input_names == dynamic.input_names == INPUT_NAMES


def test_the_models_say_what_they_read_and_what_they_carry() -> None:
    kinematic = kinematic_model(CONFIG)
    assert kinematic.estimated_state_names == kinematic.state_names
    assert kinematic.unmodelled_lag_s == CONFIG.model.steer_time_constant_s  # no actuator
    dynamic = dynamic_model(CONFIG)
    assert dict(dynamic.internal_rest_inputs) == {"road_wheel_angle_rad": "steer_rad"}
    assert dynamic.unmodelled_lag_s == 0.0  # the actuator is in the model
    assert dynamic.limit_names == ("front_slip_rad", "rear_slip_rad")


def _model(**changes: object) -> NmpcModel:
    return dataclasses.replace(kinematic_model(CONFIG), **changes)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"input_names": ("steer_rad", "accel_mps2")}, "inputs"),
        ({"state_names": ("x_m", "y_m", "speed_mps", "yaw_rad")}, "expected states"),
        ({"estimated_state_names": ("x_m", "y_m", "yaw_rad")}, "rest input"),
        ({"estimated_state_names": ("x_m", "y_m", "yaw_rad", "vx_mps", "z_m")}, "estimated"),
        ({"unmodelled_lag_s": -0.1}, "unmodelled_lag_s"),
        ({"limit_names": ("front_slip_rad",)}, "limit names"),
    ],
)
def test_bad_models_are_refused(changes: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        _model(**changes)


def test_a_step_function_of_the_wrong_size_is_refused() -> None:
    state, inputs = ca.SX.sym("state", 3), ca.SX.sym("inputs", 2)
    three_states = ca.Function("three_states", [state, inputs], [state])
    with pytest.raises(ConfigError, match="does not match"):
        _model(step=three_states)


def test_a_model_for_another_stage_length_is_refused() -> None:
    with pytest.raises(ConfigError, match="dt_s"):
        Nmpc(dataclasses.replace(CONFIG, dt_s=0.1), dynamic_model(CONFIG))
