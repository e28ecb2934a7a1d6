"""Validation of the tracker's configuration and the registry of trackers by name."""

from __future__ import annotations

import dataclasses
import math

import pytest

from cosim.core.config_fields import describe, from_dict, to_dict
from cosim.core.exceptions import ConfigError
from cosim.core.vehicle_params import VehicleParams
from tracker.config import TRACKER_CHOICES, TrackerConfig, TrackerWeights
from tracker.mpc.dynamic_nmpc import DynamicNmpc
from tracker.mpc.kinematic_nmpc import KinematicNmpc
from tracker.registry import TRACKER_NAMES, make_tracker


def test_defaults() -> None:
    config = from_dict(TrackerConfig, {}, "tracker")
    assert config == TrackerConfig()
    assert config.name == "dynamic-nmpc"
    assert 20 <= config.horizon <= 30
    assert config.dt_s == 0.05
    assert config.max_steer_rad == pytest.approx(math.pi / 8)  # the default bound, 22.5 deg
    assert (config.accel_min_mps2, config.accel_max_mps2) == (-3.0, 3.0)
    assert config.model == VehicleParams()
    assert config.latency_s == 0.0  # the default plant has no transport delay
    # The belief of dynamic models: what `cosim identify` finds on the default sedan.
    assert config.model.cornering_stiffness_front_npr == 72550.0
    assert config.model.cornering_stiffness_rear_npr == 79580.0
    assert config.model.steer_time_constant_s == 0.05
    assert config.model.max_steer_rate_radps == 0.8
    assert config.horizon_s == pytest.approx(config.horizon * config.dt_s)


def test_nested_keys_set_like_the_command_line() -> None:
    config = from_dict(
        TrackerConfig,
        {"horizon": 30, "weights": {"cte": 5.0}, "model": {"cog_front_m": 1.3}},
        "tracker",
    )
    assert config.horizon == 30
    assert config.weights.cte == 5.0
    assert config.weights.heading == TrackerWeights().heading
    assert config.model.cog_front_m == 1.3
    assert from_dict(TrackerConfig, to_dict(config), "tracker") == config


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"horizon": 0}, "tracker.horizon = 0"),
        ({"horizon": 2.5}, "tracker.horizon = 2.5: expected an integer"),
        ({"dt_s": -0.05}, "tracker.dt_s = -0.05"),
        ({"weights": {"lateral": 1.0}}, "unknown key 'tracker.weights.lateral'"),
        ({"weights": {"cte": -1.0}}, "tracker.weights.cte = -1.0"),
        ({"weights": 3}, "tracker.weights = 3"),
        ({"name": "bang-bang"}, "tracker.name = 'bang-bang'"),
        ({"horizn": 30}, "unknown key 'tracker.horizn'"),
        ({"max_steer_rad": 2.0}, "tracker.max_steer_rad = 2.0"),
        ({"max_iterations": 0}, "tracker.max_iterations = 0"),
        ({"model": {"cog_rear_m": 0.0}}, "tracker.model.cog_rear_m = 0.0"),
        ({"model": {"cornering_stiffness_front_npr": 0}},
         "tracker.model.cornering_stiffness_front_npr = 0: expected a number in"),
        ({"model": {"cornering_stiffness_rear_npr": "stiff"}},
         "tracker.model.cornering_stiffness_rear_npr = 'stiff'"),
        ({"model": {"steer_time_constant_s": -0.05}}, "tracker.model.steer_time_constant_s"),
        ({"weights": {"limit_excess": -1.0}}, "tracker.weights.limit_excess = -1.0"),
        ({"latency_s": 3.0}, "tracker.latency_s = 3.0"),
    ],
)
def test_bad_values_name_their_key(data: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace(".", r"\.").replace("(", r"\(")):
        from_dict(TrackerConfig, data, "tracker")


@pytest.mark.parametrize(
    ("data", "key"),
    [
        ({"accel_min_mps2": -1.0, "accel_max_mps2": 0.0}, "accel_min_mps2"),
        ({"max_steer_rad": 0.5, "model": {"max_steer_rad": 0.4}}, "max_steer_rad"),
        ({"accel_min_mps2": -1.0, "safe_stop_accel_mps2": -2.0}, "safe_stop_accel_mps2"),
    ],
)
def test_inconsistent_values_are_refused(data: dict, key: str) -> None:
    with pytest.raises(ConfigError, match=key):
        from_dict(TrackerConfig, data, "tracker")


def test_every_key_is_documented() -> None:
    rows = describe(TrackerConfig, "tracker")
    keys = {key for key, _, _ in rows}
    assert "tracker.weights.steer_rate" in keys
    assert "tracker.model.mass_kg" in keys
    for field in dataclasses.fields(TrackerWeights):
        assert field.metadata["doc"], field.name


def test_registry_knows_every_configurable_name() -> None:
    assert TRACKER_NAMES == TRACKER_CHOICES
    assert isinstance(make_tracker(TrackerConfig()), DynamicNmpc)
    kinematic = dataclasses.replace(TrackerConfig(), name="kinematic-nmpc")
    assert isinstance(make_tracker(kinematic), KinematicNmpc)


def test_the_mathworks_example_tyres_are_a_belief_one_can_state() -> None:
    config = from_dict(TrackerConfig, {"model": {"cornering_stiffness_front_npr": 19000,
                                                 "cornering_stiffness_rear_npr": 33000}},
                       "tracker")
    assert config.model.cornering_stiffness_front_npr == 19000.0
    assert isinstance(make_tracker(config), DynamicNmpc)


def test_registry_refuses_unknown_names() -> None:
    """The config refuses an unknown name (neither built in nor a plug-in) as it is made."""
    with pytest.raises(ConfigError, match="name = 'follow-the-carrot'.*kinematic-nmpc"):
        make_tracker(dataclasses.replace(TrackerConfig(), name="follow-the-carrot"))
