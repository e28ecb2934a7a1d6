"""Noisy sensors: GNSS position, IMU (yaw rate and acceleration), wheel speeds, and truth.

MuJoCo adds no sensor noise (since 3.1.4); noise, rates and later bias and faults are
modelled here, as properties of the observation and not of the physics (as dm_control's
observables do). Each sensor draws its noise from its own generator, which the runner
derives from the run's seed and the sensor's name, so adding a sensor changes no other
sensor's noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosim.config_fields import section, setting
from cosim.records import WHEEL_NAMES, Measurement, VehicleState


@dataclass(frozen=True)
class GnssConfig:
    """GNSS receiver: position of the antenna (at the centre of gravity)."""

    enabled: bool = setting(True)
    period_s: float = setting(0.1, low=0.001, high=10.0)
    sigma_m: float = setting(0.02, low=0.0, high=100.0, doc="per horizontal axis")


@dataclass(frozen=True)
class ImuConfig:
    """IMU at the centre of gravity: yaw rate and horizontal kinematic acceleration."""

    enabled: bool = setting(True)
    period_s: float = setting(0.01, low=0.001, high=10.0)
    gyro_sigma_radps: float = setting(0.005, low=0.0, high=10.0)
    accel_sigma_mps2: float = setting(0.05, low=0.0, high=100.0)


@dataclass(frozen=True)
class WheelSpeedConfig:
    """Wheel-speed (ABS) sensors on all four wheels."""

    enabled: bool = setting(True)
    period_s: float = setting(0.01, low=0.001, high=10.0)
    sigma_radps: float = setting(0.05, low=0.0, high=100.0)


@dataclass(frozen=True)
class SensorsConfig:
    """The car's sensor suite."""

    gnss: GnssConfig = section(GnssConfig)
    imu: ImuConfig = section(ImuConfig)
    wheel_speed: WheelSpeedConfig = section(WheelSpeedConfig)


class GnssSensor:
    """World-frame position of the centre of gravity with white Gaussian noise."""

    name = "gnss"
    names = ("x_m", "y_m")

    def __init__(self, config: GnssConfig) -> None:
        self.period_s = config.period_s
        self._sigma_m = config.sigma_m
        self._covariance = np.eye(2) * config.sigma_m**2

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement:
        values = np.array([truth.x_m, truth.y_m]) + rng.normal(0.0, self._sigma_m, 2)
        return Measurement(self.name, truth.t_s, self.names, values, self._covariance)


class ImuSensor:
    """Yaw rate and the kinematic acceleration of the CoG in the vehicle frame.

    Gravity is taken as already removed (an ideal attitude-compensated IMU); bias and
    gravity leakage through roll and pitch come with the sensor-suite issue.
    """

    name = "imu"
    names = ("yaw_rate_radps", "ax_mps2", "ay_mps2")

    def __init__(self, config: ImuConfig) -> None:
        self.period_s = config.period_s
        self._sigma = np.array(
            [config.gyro_sigma_radps, config.accel_sigma_mps2, config.accel_sigma_mps2]
        )
        self._covariance = np.diag(self._sigma**2)

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement:
        values = np.array([truth.yaw_rate_radps, truth.ax_mps2, truth.ay_mps2])
        values = values + rng.normal(0.0, 1.0, 3) * self._sigma
        return Measurement(self.name, truth.t_s, self.names, values, self._covariance)


class WheelSpeedSensor:
    """Spin rate of each wheel (positive rolling forward), in WHEEL_NAMES order."""

    name = "wheel_speed"
    names = tuple(f"{wheel}_radps" for wheel in WHEEL_NAMES)

    def __init__(self, config: WheelSpeedConfig) -> None:
        self.period_s = config.period_s
        self._sigma = config.sigma_radps
        self._covariance = np.eye(4) * config.sigma_radps**2

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement:
        values = np.asarray(truth.wheel_speed_radps, dtype=float) + rng.normal(
            0.0, self._sigma, 4
        )
        return Measurement(self.name, truth.t_s, self.names, values, self._covariance)


TRUTH_FIELDS = (
    "x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad", "vx_mps", "vy_mps",
    "yaw_rate_radps", "ax_mps2", "ay_mps2", "steer_rad",
)


class TruthSensor:
    """The true state as a noise-free measurement: feeds only the ``truth`` estimator."""

    name = "truth"
    names = TRUTH_FIELDS

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self._covariance = np.zeros((len(TRUTH_FIELDS), len(TRUTH_FIELDS)))

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement:
        del rng  # noise-free by definition
        values = np.array([getattr(truth, name) for name in TRUTH_FIELDS])
        return Measurement(self.name, truth.t_s, self.names, values, self._covariance)


def make_sensors(config: SensorsConfig) -> list[GnssSensor | ImuSensor | WheelSpeedSensor]:
    """The enabled sensors of the suite, in a fixed order."""
    sensors: list[GnssSensor | ImuSensor | WheelSpeedSensor] = []
    if config.gnss.enabled:
        sensors.append(GnssSensor(config.gnss))
    if config.imu.enabled:
        sensors.append(ImuSensor(config.imu))
    if config.wheel_speed.enabled:
        sensors.append(WheelSpeedSensor(config.wheel_speed))
    return sensors
