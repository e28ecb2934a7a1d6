"""The forward range sensor: target choice, geometry, noise, dropouts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.core.records import VehicleState
from cosim.core.traffic_records import CarPose
from cosim.sensing.range_sensor import RadarConfig, RangeSensor

FRONT_M = 2.0


def ego(x_m: float = 0.0, y_m: float = 0.0, yaw_rad: float = 0.0,
        vx_mps: float = 20.0) -> VehicleState:
    return VehicleState(t_s=1.0, x_m=x_m, y_m=y_m, z_m=0.5, roll_rad=0.0, pitch_rad=0.0,
                        yaw_rad=yaw_rad, vx_mps=vx_mps, vy_mps=0.0, yaw_rate_radps=0.0,
                        ax_mps2=0.0, ay_mps2=0.0, steer_rad=0.0,
                        wheel_speed_radps=(0.0, 0.0, 0.0, 0.0))


def car(name: str, x_m: float, y_m: float, speed_mps: float = 15.0,
        yaw_rad: float = 0.0) -> CarPose:
    return CarPose(name=name, t_s=1.0, x_m=x_m, y_m=y_m, yaw_rad=yaw_rad,
                   speed_mps=speed_mps, accel_mps2=0.0, length_m=4.0, width_m=1.8)


def exact(**settings: float) -> RangeSensor:
    return RangeSensor(RadarConfig(gap_sigma_m=0.0, range_rate_sigma_mps=0.0, **settings),
                       FRONT_M)


def test_the_gap_runs_from_the_front_bumper_to_the_targets_rear() -> None:
    found, gap, rate = exact().true_target(ego(), [car("a", 32.0, 0.5)])
    assert found is not None and found.name == "a"
    assert gap == pytest.approx(32.0 - 2.0 - FRONT_M)
    assert rate == pytest.approx(15.0 - 20.0)


def test_the_nearest_car_in_the_lane_is_the_target() -> None:
    cars = [car("far", 80.0, 0.0), car("near", 40.0, -1.0), car("next_lane", 20.0, 3.5),
            car("behind", -20.0, 0.0)]
    reading = exact().sample(ego(), cars, np.random.default_rng(0))
    assert reading is not None and reading.target == "near"


def test_the_lane_turns_with_the_ego() -> None:
    yaw = math.radians(30.0)
    ahead = car("ahead", 40.0 * math.cos(yaw), 40.0 * math.sin(yaw), yaw_rad=yaw)
    on_old_heading = car("old", 30.0, 0.0)
    found, gap, _ = exact().true_target(ego(yaw_rad=yaw), [ahead, on_old_heading])
    assert found is ahead
    assert gap == pytest.approx(40.0 - 2.0 - FRONT_M)


@pytest.mark.parametrize(("settings", "position"), [
    ({"max_range_m": 50.0}, (60.0, 0.0)),
    ({"fov_rad": math.radians(10.0)}, (14.0, 1.5)),  # 1.5 m left at 10 m: 8.5 deg off axis
    ({"lane_half_width_m": 1.0}, (30.0, 1.5)),
])
def test_a_car_outside_range_view_or_lane_is_not_seen(settings, position) -> None:
    reading = exact(**settings).sample(ego(), [car("a", *position)], np.random.default_rng(0))
    assert reading is not None
    assert reading.target == "" and not reading.has_target and math.isnan(reading.gap_m)
    seen = exact().sample(ego(), [car("a", *position)], np.random.default_rng(0))
    assert seen is not None and seen.target == "a"


def test_noise_has_the_configured_spread_and_no_bias() -> None:
    sensor = RangeSensor(RadarConfig(gap_sigma_m=0.3, range_rate_sigma_mps=0.1), FRONT_M)
    rng = np.random.default_rng(1)
    readings = [sensor.sample(ego(), [car("a", 50.0, 0.0)], rng) for _ in range(4000)]
    gaps = np.array([r.gap_m for r in readings if r is not None])
    rates = np.array([r.range_rate_mps for r in readings if r is not None])
    assert gaps.mean() == pytest.approx(46.0, abs=0.03)  # 4 sigma of the mean of 4000
    assert gaps.std() == pytest.approx(0.3, rel=0.05)
    assert rates.mean() == pytest.approx(-5.0, abs=0.01)
    assert rates.std() == pytest.approx(0.1, rel=0.05)


def test_dropouts_lose_the_configured_share_of_samples() -> None:
    sensor = RangeSensor(RadarConfig(dropout_probability=0.2), FRONT_M)
    rng = np.random.default_rng(2)
    lost = sum(sensor.sample(ego(), [car("a", 50.0, 0.0)], rng) is None for _ in range(5000))
    assert lost / 5000 == pytest.approx(0.2, abs=0.02)  # 3.5 sigma of a binomial share


def test_one_seed_one_sequence() -> None:
    sensor = RangeSensor(RadarConfig(dropout_probability=0.3), FRONT_M)
    first = [sensor.sample(ego(), [car("a", 50.0, 0.0)], rng)
             for rng in [np.random.default_rng(5)] for _ in range(50)]
    second = [sensor.sample(ego(), [car("a", 50.0, 0.0)], rng)
              for rng in [np.random.default_rng(5)] for _ in range(50)]
    assert first == second
