"""Sensors, suites and faults: noise, bias, quantisation and fault injection as data."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from cosim.core.records import Measurement, VehicleState
from cosim.sensing.faults import FaultConfig, FaultInjector
from cosim.sensing.sensors import (
    GnssConfig,
    GnssSensor,
    GnssVelocityConfig,
    GnssVelocitySensor,
    HeadingConfig,
    HeadingSensor,
    ImuConfig,
    ImuSensor,
    WheelSpeedConfig,
    WheelSpeedSensor,
    make_sensors,
)
from cosim.simulation.runner import component_rng
from cosim.simulation.scenario_config import load_config


def _truth(t_s: float = 0.0, yaw_rad: float = 0.0) -> VehicleState:
    return VehicleState(t_s=t_s, x_m=10.0, y_m=-2.0, z_m=0.5, roll_rad=0.0, pitch_rad=0.0,
                        yaw_rad=yaw_rad, vx_mps=20.0, vy_mps=0.1, yaw_rate_radps=0.2,
                        ax_mps2=1.0, ay_mps2=4.0, steer_rad=0.03,
                        wheel_speed_radps=(64.0, 65.0, 64.5, 65.5))


def test_suites_preset_figures_and_explicit_values_win() -> None:
    assert load_config("lane-change").sensors.gnss.sigma_m == 0.02
    assert load_config("lane-change", overrides=["sensors.suite=gnss"]).sensors.gnss.sigma_m == 0.5
    ideal = load_config("lane-change", overrides=["sensors.suite=ideal"]).sensors
    assert ideal.gnss.sigma_m == 0.0 and ideal.imu.gyro_bias_sigma_radps == 0.0
    assert ideal.wheel_speed.quantum_radps == 0.0
    mixed = load_config("lane-change", overrides=["sensors.suite=gnss",
                                                  "sensors.gnss.sigma_m=0.1"]).sensors
    assert mixed.gnss.sigma_m == 0.1
    with pytest.raises(ConfigError, match="sensors.suite = 'lidar'"):
        load_config("lane-change", overrides=["sensors.suite=lidar"])


def test_gnss_noise_has_the_configured_spread() -> None:
    sensor, rng = GnssSensor(GnssConfig(sigma_m=0.5)), np.random.default_rng(1)
    errors = np.array([sensor.sample(_truth(), rng).values - [10.0, -2.0]
                       for _ in range(4000)])
    assert np.std(errors, axis=0) == pytest.approx([0.5, 0.5], rel=0.05)
    assert np.abs(np.mean(errors, axis=0)).max() < 0.03


def test_gnss_velocity_is_the_world_frame_velocity_with_its_noise() -> None:
    """Doppler velocity: the vehicle-frame (vx, vy) = (20, 0.1) m/s turned by the yaw into
    east and north; on in the rtk suite (the default), off in the gnss suite unless
    enabled."""
    def names(*overrides: str) -> list[str]:
        config = load_config("lane-change", overrides=overrides)
        return [s.name for s in make_sensors(config.sensors)]

    assert "gnss_velocity" in names() and "gnss_velocity" in names("sensors.suite=rtk")
    assert "gnss_velocity" not in names("sensors.suite=gnss")
    assert "gnss_velocity" in names("sensors.suite=gnss", "sensors.gnss_velocity.enabled=true")
    exact = GnssVelocitySensor(GnssVelocityConfig(sigma_mps=0.0))
    rng = np.random.default_rng(3)
    np.testing.assert_allclose(exact.sample(_truth(yaw_rad=0.0), rng).values, [20.0, 0.1])
    np.testing.assert_allclose(exact.sample(_truth(yaw_rad=math.pi / 2), rng).values,
                               [-0.1, 20.0], atol=1e-12)
    noisy = GnssVelocitySensor(GnssVelocityConfig(sigma_mps=0.05))
    errors = np.array([noisy.sample(_truth(), rng).values - [20.0, 0.1] for _ in range(4000)])
    assert np.std(errors, axis=0) == pytest.approx([0.05, 0.05], rel=0.05)


@pytest.mark.slow
def test_imu_bias_is_constant_without_walk_and_wanders_with_it() -> None:
    fixed = ImuSensor(ImuConfig(gyro_sigma_radps=0.0, accel_sigma_mps2=0.0,
                                gyro_bias_sigma_radps=0.01, gyro_bias_walk_radps=0.0,
                                accel_bias_sigma_mps2=0.0, accel_bias_walk_mps2=0.0))
    rng = np.random.default_rng(2)
    readings = [fixed.sample(_truth(), rng)["yaw_rate_radps"] for _ in range(100)]
    assert np.ptp(readings) == 0.0 and readings[0] != 0.2
    # A random walk of 0.01 rad/s per sqrt(s) sampled at 100 Hz: after 25 s the spread
    # over many independent sensors is 0.01 * sqrt(25) = 0.05 rad/s.
    finals = []
    for seed in range(150):
        walking = ImuSensor(ImuConfig(gyro_sigma_radps=0.0, gyro_bias_sigma_radps=0.0,
                                      gyro_bias_walk_radps=0.01, period_s=0.01))
        rng = np.random.default_rng(seed)
        for _ in range(2_501):
            reading = walking.sample(_truth(), rng)
        finals.append(reading["yaw_rate_radps"] - 0.2)
    assert np.std(finals) == pytest.approx(0.05, rel=0.2)


def test_wheel_speeds_are_quantised() -> None:
    sensor = WheelSpeedSensor(WheelSpeedConfig(sigma_radps=0.03, quantum_radps=0.25))
    values = sensor.sample(_truth(), np.random.default_rng(3)).values
    assert np.allclose(values / 0.25, np.round(values / 0.25))
    assert np.allclose(values, [64.0, 65.0, 64.5, 65.5], atol=0.25)


def test_heading_is_wrapped() -> None:
    sensor = HeadingSensor(HeadingConfig(sigma_rad=0.01))
    yaws = [sensor.sample(_truth(yaw_rad=math.pi - 1e-4), np.random.default_rng(s))["yaw_rad"]
            for s in range(50)]
    assert all(-math.pi < y <= math.pi for y in yaws)
    assert any(y < 0.0 for y in yaws)  # noise across +pi wraps to near -pi


def test_component_streams_depend_on_the_name_only() -> None:
    first = component_rng(7, "sensors.gnss").normal(size=5)
    again = component_rng(7, "sensors.gnss").normal(size=5)
    other = component_rng(7, "sensors.imu").normal(size=5)
    assert np.array_equal(first, again)
    assert not np.array_equal(first, other)


def _gnss(t_s: float) -> Measurement:
    return Measurement("gnss", t_s, ("x_m", "y_m"), np.array([1.0, 2.0]), np.eye(2))


def test_dropout_swallows_the_window_only() -> None:
    injector = FaultInjector((FaultConfig(kind="dropout", start_s=1.0, end_s=2.0),),
                             "gnss", ("x_m", "y_m"))
    delivered = [injector.apply(_gnss(t)) for t in (0.9, 1.0, 1.5, 2.0)]
    assert [m is None for m in delivered] == [False, True, True, False]
    assert injector.injected == 2


def test_single_outlier_hits_the_first_sample_at_its_time() -> None:
    injector = FaultInjector((FaultConfig(kind="outlier", start_s=1.05, offset=20.0,
                                          offset_north=-5.0),), "gnss", ("x_m", "y_m"))
    values = [injector.apply(_gnss(t)).values for t in (1.0, 1.1, 1.2)]
    assert np.array_equal(values[0], [1.0, 2.0])
    assert np.array_equal(values[1], [21.0, -3.0])
    assert np.array_equal(values[2], [1.0, 2.0])


def test_gnss_velocity_outlier_splits_east_and_north() -> None:
    names = ("v_east_mps", "v_north_mps")
    injector = FaultInjector((FaultConfig(kind="outlier", sensor="gnss_velocity", start_s=1.0,
                                          offset=2.0, offset_north=-1.0),), "gnss_velocity", names)
    velocity = Measurement("gnss_velocity", 1.0, names, np.array([20.0, 0.5]), np.eye(2))
    assert np.array_equal(injector.apply(velocity).values, [22.0, -0.5])


def test_stuck_and_nan_act_on_the_chosen_channel() -> None:
    channels = ("yaw_rate_radps", "ax_mps2", "ay_mps2")
    faults = (FaultConfig(kind="stuck", sensor="imu", start_s=1.0, end_s=3.0,
                          channel="ax_mps2"),
              FaultConfig(kind="nan", sensor="imu", start_s=2.0, end_s=3.0, channel="ay_mps2"))
    injector = FaultInjector(faults, "imu", channels)

    def imu(t_s: float, value: float) -> Measurement:
        return Measurement("imu", t_s, channels, np.full(3, value), np.eye(3))

    assert np.array_equal(injector.apply(imu(0.5, 1.0)).values, [1.0, 1.0, 1.0])
    assert np.array_equal(injector.apply(imu(1.5, 2.0)).values, [2.0, 1.0, 2.0])
    late = injector.apply(imu(2.5, 3.0)).values
    assert late[0] == 3.0 and late[1] == 1.0 and math.isnan(late[2])
    assert np.array_equal(injector.apply(imu(3.5, 4.0)).values, [4.0, 4.0, 4.0])


def test_bad_faults_are_config_errors() -> None:
    with pytest.raises(ConfigError, match="channel = 'speed'"):
        FaultInjector((FaultConfig(kind="nan", sensor="imu", channel="speed"),), "imu",
                      ("yaw_rate_radps", "ax_mps2", "ay_mps2"))
    with pytest.raises(ConfigError, match=r"faults\[0\].end_s = 1.0"):
        load_config("lane-change", overrides=["faults=[{start_s: 2, end_s: 1}]"])
    with pytest.raises(ConfigError, match=r"faults\[0\].kind = 'glitch'"):
        load_config("lane-change", overrides=["faults=[{kind: glitch}]"])
