"""Scenario configuration: loading, overrides, validation errors, the rate check."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.core.exceptions import ConfigError, RateError
from cosim.simulation.scenario_config import builtin_scenarios, load_config


def test_builtin_lane_change_matches_the_seed_digest() -> None:
    config = load_config("lane-change")
    assert config.path.stretch == 1.5
    assert config.path.speed_mps == 20.0
    assert config.initial.speed_mps == 15.0
    assert config.sim.duration_s == 15.0
    assert config.plant.mass_kg == 1575.0
    assert config.plant.yaw_inertia_kgm2 == 2875.0
    assert (config.plant.cog_front_m, config.plant.cog_rear_m) == (1.2, 1.6)
    assert config.tracker.name == "dynamic-nmpc"
    assert config.estimator.name == "ekf"


def test_limit_scenario_uses_falcones_constants() -> None:
    assert load_config("lane-change-limit").path.stretch == 1.0
    assert {"lane-change", "lane-change-limit"} <= set(builtin_scenarios())


def test_overrides_reach_nested_keys_with_yaml_types() -> None:
    config = load_config("lane-change", overrides=["tracker.horizon=12", "plant.mass_kg=2000",
                                                   "sensors.heading.enabled=true"],
                         seed=7, duration_s=3.0)
    assert config.tracker.horizon == 12
    assert config.plant.mass_kg == 2000.0
    assert config.sensors.heading.enabled is True
    assert config.seed == 7
    assert config.sim.duration_s == 3.0
    # The controller's belief is independent of the plant's truth: mismatch as data.
    assert config.tracker.model.mass_kg == 1575.0


@pytest.mark.parametrize(
    ("override", "fragment"),
    [
        ("tracker.horizn=30", "unknown key 'tracker.horizn'"),
        ("plant.mass_kg=-5", "plant.mass_kg = -5: expected a number in [100, 20000]"),
        ("plant.mass_kg=heavy", "plant.mass_kg = 'heavy': expected a number"),
        ("tracker.horizon=2.5", "tracker.horizon = 2.5: expected an integer"),
        ("plant.drive=4wd", "plant.drive = '4wd': expected one of 'rwd', 'fwd', 'awd'"),
        ("sensors.gnss.enabled=maybe", "sensors.gnss.enabled = 'maybe': expected true or false"),
        ("plant.mass_kg.x=1", "plant.mass_kg = {'x': 1}: expected a number"),
        ("nonsense", "expected key.path=value"),
        ("sim=3", "sim = 3: expected a mapping"),
        ("plant.track_rear_m=3.5", "plant.track_rear_m = 3.5: expected a number in [0, 3]"),
        ("tracker.model.track_front_m=0.2",
         "tracker.model.track_front_m = 0.2: expected 0 (track_m) or a track in [0.5, 3] m"),
        ("plant.tyre.longitudinal_friction_scale=4",
         "plant.tyre.longitudinal_friction_scale = 4: expected a number in [0.1, 3]"),
        # A bound that six digits would round to the refused value is written out.
        ("estimator.gate_probability=1",
         "estimator.gate_probability = 1: expected a number in [0.5, 0.999999999]"),
    ],
)
def test_bad_values_name_the_key_and_the_expectation(override: str, fragment: str) -> None:
    with pytest.raises(ConfigError) as error:
        load_config("lane-change", overrides=[override])
    assert fragment in str(error.value)


def test_unknown_scenario_lists_the_builtins() -> None:
    with pytest.raises(ConfigError, match="expected a built-in name .*lane-change"):
        load_config("no-such-scenario")


def test_scenario_file_and_config_file_merge(tmp_path: Path) -> None:
    scenario = tmp_path / "mine.yaml"
    scenario.write_text("path:\n  speed_mps: 12.0\ninitial:\n  speed_mps: 10.0\n")
    extra = tmp_path / "extra.yaml"
    extra.write_text("tracker:\n  horizon: 15\n")
    config = load_config(str(scenario), config_file=str(extra))
    assert config.name == "mine"
    assert config.path.speed_mps == 12.0
    assert config.tracker.horizon == 15
    broken = tmp_path / "broken.yaml"
    broken.write_text("path: [unclosed\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(str(broken))


@pytest.mark.parametrize(
    ("override", "key"),
    [
        ("sim.control_period_s=0.051", "sim.control_period_s = 0.051"),
        ("sensors.gnss.period_s=0.0125", "sensors.gnss.period_s = 0.0125"),
        ("plant.actuator_delay_s=0.003", "plant.actuator_delay_s = 0.003"),
        ("sim.log_period_s=0.001", "sim.log_period_s = 0.001"),
    ],
)
def test_periods_must_be_whole_physics_steps(override: str, key: str) -> None:
    with pytest.raises(RateError) as error:
        load_config("lane-change", overrides=[override])
    assert key in str(error.value)
    assert "whole multiple of sim.physics_dt_s = 0.002" in str(error.value) or \
        "expected at least" in str(error.value)


def test_whole_multiples_are_accepted() -> None:
    config = load_config("lane-change", overrides=["sim.control_period_s=0.02",
                                                   "plant.actuator_delay_s=0.1",
                                                   "sim.physics_dt_s=0.001"])
    assert config.sim.control_period_s == 0.02


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("sim.scene_period_s=0.035", "sim.scene_period_s = 0.035: expected a whole multiple "
                                     "of sim.log_period_s = 0.01 (e.g. 0.03 or 0.04)"),
        ("sim.scene_period_s=0.004", "sim.scene_period_s = 0.004: expected a whole multiple "
                                     "of sim.log_period_s = 0.01 (e.g. 0.01 or 0.02)"),
    ],
)
def test_the_scene_period_is_whole_log_periods(override: str, message: str) -> None:
    with pytest.raises(RateError) as error:
        load_config("lane-change", overrides=[override])
    assert str(error.value) == message


def test_a_steering_limit_above_one_radian_is_a_key_the_tracker_may_use() -> None:
    """CommonRoad's BMW 320i turns its front wheels up to 1.066 rad: plant, belief and the
    tracker's own bound accept it (each bound at most the belief's)."""
    config = load_config("lane-change", overrides=[
        "plant.max_steer_rad=1.066", "tracker.model.max_steer_rad=1.066",
        "tracker.max_steer_rad=1.066"])
    assert config.plant.max_steer_rad == config.tracker.max_steer_rad == 1.066


def test_axle_tracks_fall_back_to_track_m() -> None:
    config = load_config("lane-change", overrides=["plant.track_m=1.5",
                                                   "plant.track_rear_m=1.55"])
    assert config.plant.axle_tracks_m == (1.5, 1.55)
    assert config.plant.widest_track_m == 1.55
    assert config.tracker.model.axle_tracks_m == (1.6, 1.6)  # the belief keeps its own
