"""Noisy sensors: GNSS position and velocity, IMU (yaw rate and acceleration), wheel speeds,
and truth.

MuJoCo adds no sensor noise (since 3.1.4); noise, rates and later bias and faults are
modelled here, as properties of the observation and not of the physics (as dm_control's
observables do). Each sensor draws its noise from its own generator, which the runner
derives from the run's seed and the sensor's name, so adding a sensor changes no other
sensor's noise.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from cosim.core import sensor_names
from cosim.core.config_fields import section, setting
from cosim.core.records import WHEEL_NAMES, Measurement, VehicleState
from cosim.sensing.protocol import Sensor
from cosim.sensing.range_sensor import RadarConfig

SENSOR_SUITES = ("rtk", "gnss", "ideal")


@dataclass(frozen=True)
class GnssConfig:
    """GNSS receiver: position of the antenna (at the centre of gravity)."""

    enabled: bool = setting(True)
    period_s: float = setting(0.1, low=0.001, high=10.0)
    sigma_m: float = setting(0.02, low=0.0, high=100.0, doc="per horizontal axis")
    latency_s: float = setting(
        0.0, low=0.0, high=1.0,
        doc="from a fix's measurement to its delivery, its position and its Doppler velocity "
        "alike (receivers: 0.05-0.2 s); the fix keeps its measurement time, and a filter "
        "fuses it there only with estimator.history_s",
    )


@dataclass(frozen=True)
class GnssVelocityConfig:
    """GNSS velocity from the carriers' Doppler shift: the CoG's velocity over the ground in
    the world frame (east, north). On in the ``rtk`` suite (the default), whose receivers
    report it with each fix (u-blox ZED-F9P data sheet: 0.05 m/s); off in the ``gnss``
    suite, a receiver read for its position only."""

    enabled: bool = setting(True)
    period_s: float = setting(0.1, low=0.001, high=10.0)
    sigma_mps: float = setting(
        0.05, low=0.0, high=10.0, doc="per horizontal axis (0.05 m/s: automotive receivers)"
    )


@dataclass(frozen=True)
class HeadingConfig:
    """Dual-antenna GNSS heading: the yaw of the baseline between two antennas."""

    enabled: bool = setting(False)
    period_s: float = setting(0.1, low=0.001, high=10.0)
    sigma_rad: float = setting(0.003, low=0.0, high=1.0, doc="about 0.17 deg: 1-2 m baseline")


@dataclass(frozen=True)
class ImuConfig:
    """IMU at the centre of gravity: yaw rate and horizontal kinematic acceleration.

    Each channel has white noise plus a bias that starts at a random value
    (``*_bias_sigma``) and wanders as a random walk (``*_bias_walk``, the standard deviation
    of the bias change over one second).
    """

    enabled: bool = setting(True)
    period_s: float = setting(0.01, low=0.001, high=10.0)
    gyro_sigma_radps: float = setting(0.005, low=0.0, high=10.0)
    gyro_bias_sigma_radps: float = setting(0.002, low=0.0, high=1.0, doc="initial bias spread")
    gyro_bias_walk_radps: float = setting(0.0002, low=0.0, high=1.0, doc="bias change per sqrt(s)")
    accel_sigma_mps2: float = setting(0.05, low=0.0, high=100.0)
    accel_bias_sigma_mps2: float = setting(0.02, low=0.0, high=10.0, doc="initial bias spread")
    accel_bias_walk_mps2: float = setting(0.002, low=0.0, high=10.0, doc="bias change per sqrt(s)")


@dataclass(frozen=True)
class WheelSpeedConfig:
    """Wheel-speed (ABS) sensors on all four wheels."""

    enabled: bool = setting(True)
    period_s: float = setting(0.01, low=0.001, high=10.0)
    sigma_radps: float = setting(0.05, low=0.0, high=100.0)
    quantum_radps: float = setting(0.01, low=0.0, high=10.0, doc="resolution (0: none)")


@dataclass(frozen=True)
class SteeringConfig:
    """Steering-angle sensor, converted to the mean front road-wheel angle."""

    enabled: bool = setting(True)
    period_s: float = setting(0.01, low=0.001, high=10.0)
    sigma_rad: float = setting(0.001, low=0.0, high=1.0)
    quantum_rad: float = setting(0.0005, low=0.0, high=0.1, doc="resolution (0: none)")


@dataclass(frozen=True)
class SensorsConfig:
    """The car's sensor suite. ``suite`` presets the figures (see :func:`suite_preset`);
    any figure set explicitly (``--set sensors.gnss.sigma_m=0.1``) wins over the preset."""

    suite: str = setting("rtk", choices=SENSOR_SUITES)
    gnss: GnssConfig = section(GnssConfig)
    gnss_velocity: GnssVelocityConfig = section(GnssVelocityConfig)
    heading: HeadingConfig = section(HeadingConfig)
    imu: ImuConfig = section(ImuConfig)
    wheel_speed: WheelSpeedConfig = section(WheelSpeedConfig)
    steering: SteeringConfig = section(SteeringConfig)
    radar: RadarConfig = section(RadarConfig)
    """The forward range sensor of the ACC (:mod:`cosim.sensing.range_sensor`): sampled
    only in scenarios with traffic, and not fused by the state estimator."""


def suite_preset(suite: str) -> dict[str, dict[str, float]]:
    """The figures a named suite changes from the defaults, as a ``sensors:`` mapping.

    - ``rtk`` (the defaults): RTK-corrected GNSS (2 cm) with its Doppler velocity
      (0.05 m/s), an automotive MEMS IMU (gyro bias of about 0.1 deg/s), ABS wheel
      encoders, an EPS steering-angle sensor;
    - ``gnss``: the same car with a standalone GNSS receiver's position (0.5 m), no velocity;
    - ``ideal``: every sensor noise-free, unbiased and unquantised, for debugging.
    """
    if suite == "gnss":
        return {sensor_names.GNSS: {"sigma_m": 0.5},
                sensor_names.GNSS_VELOCITY: {"enabled": False}}
    if suite == "ideal":
        zero = {sensor_names.GNSS: GnssConfig, sensor_names.GNSS_VELOCITY: GnssVelocityConfig,
                sensor_names.HEADING: HeadingConfig, sensor_names.IMU: ImuConfig,
                sensor_names.WHEEL_SPEED: WheelSpeedConfig,
                sensor_names.STEERING: SteeringConfig}
        return {
            name: {f.name: 0.0 for f in dataclasses.fields(cls)
                   if f.name not in ("enabled", "period_s")}
            for name, cls in zero.items()
        }
    return {}


def _quantise(values: np.ndarray, quantum: float) -> np.ndarray:
    # np.rint: np.round's own rounding (half to even) without its wrappers
    return np.rint(values / quantum) * quantum if quantum > 0.0 else values


class _HorizontalGaussianSensor:
    """Two horizontal world-frame channels with the same white Gaussian noise on each."""

    name: str
    names: tuple[str, str]

    def __init__(self, period_s: float, sigma: float) -> None:
        self.period_s = period_s
        self._sigma = sigma
        self._covariance = np.eye(2) * sigma**2

    def _exact(self, truth: VehicleState) -> np.ndarray:
        raise NotImplementedError

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement:
        values = self._exact(truth) + rng.normal(0.0, self._sigma, 2)
        return Measurement(self.name, truth.t_s, self.names, values, self._covariance)


class GnssSensor(_HorizontalGaussianSensor):
    """World-frame position of the centre of gravity with white Gaussian noise."""

    name = sensor_names.GNSS
    names = ("x_m", "y_m")

    def __init__(self, config: GnssConfig) -> None:
        super().__init__(config.period_s, config.sigma_m)

    def _exact(self, truth: VehicleState) -> np.ndarray:
        return np.array([truth.x_m, truth.y_m])


class GnssVelocitySensor(_HorizontalGaussianSensor):
    """World-frame velocity of the centre of gravity (Doppler) with white Gaussian noise:
    east ``vx cos(yaw) - vy sin(yaw)``, north ``vx sin(yaw) + vy cos(yaw)``."""

    name = sensor_names.GNSS_VELOCITY
    names = ("v_east_mps", "v_north_mps")

    def __init__(self, config: GnssVelocityConfig) -> None:
        super().__init__(config.period_s, config.sigma_mps)

    def _exact(self, truth: VehicleState) -> np.ndarray:
        cos_yaw, sin_yaw = np.cos(truth.yaw_rad), np.sin(truth.yaw_rad)
        return np.array([truth.vx_mps * cos_yaw - truth.vy_mps * sin_yaw,
                         truth.vx_mps * sin_yaw + truth.vy_mps * cos_yaw])


class ImuSensor:
    """Yaw rate and the kinematic acceleration of the CoG in the vehicle frame, with white
    noise and a random-walk bias on each channel.

    Gravity is taken as already removed (an ideal attitude-compensated IMU).
    """

    name = sensor_names.IMU
    names = ("yaw_rate_radps", "ax_mps2", "ay_mps2")

    def __init__(self, config: ImuConfig) -> None:
        self.period_s = config.period_s
        self._sigma = np.array(
            [config.gyro_sigma_radps, config.accel_sigma_mps2, config.accel_sigma_mps2]
        )
        self._bias_sigma = np.array([config.gyro_bias_sigma_radps,
                                     config.accel_bias_sigma_mps2,
                                     config.accel_bias_sigma_mps2])
        self._bias_step = np.array([config.gyro_bias_walk_radps, config.accel_bias_walk_mps2,
                                    config.accel_bias_walk_mps2]) * np.sqrt(config.period_s)
        self._bias: np.ndarray | None = None
        self._covariance = np.diag(self._sigma**2)

    @property
    def bias(self) -> np.ndarray:
        """The current bias of each channel (zeros before the first sample)."""
        return np.zeros(3) if self._bias is None else self._bias.copy()

    BIAS_NAMES = ("gyro_bias_radps", "ax_bias_mps2", "ay_bias_mps2")
    """The bias of each channel, in :attr:`names` order, by the name the filters' bias
    states have (:class:`cosim.sensing.protocol.BiasedSensor`)."""

    def true_biases(self) -> dict[str, float]:
        """The bias each channel has now (zeros before the first sample)."""
        return dict(zip(self.BIAS_NAMES, self.bias.tolist(), strict=True))

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement:
        if self._bias is None:
            self._bias = rng.normal(0.0, 1.0, 3) * self._bias_sigma
        else:
            self._bias = self._bias + rng.normal(0.0, 1.0, 3) * self._bias_step
        values = np.array([truth.yaw_rate_radps, truth.ax_mps2, truth.ay_mps2])
        values = values + self._bias + rng.normal(0.0, 1.0, 3) * self._sigma
        return Measurement(self.name, truth.t_s, self.names, values, self._covariance)


class WheelSpeedSensor:
    """Spin rate of each wheel (positive rolling forward), in WHEEL_NAMES order."""

    name = sensor_names.WHEEL_SPEED
    names = tuple(f"{wheel}_radps" for wheel in WHEEL_NAMES)

    def __init__(self, config: WheelSpeedConfig) -> None:
        self.period_s = config.period_s
        self._sigma = config.sigma_radps
        self._quantum = config.quantum_radps
        # Quantisation adds the variance of a uniform error, quantum^2 / 12.
        self._covariance = np.eye(4) * (config.sigma_radps**2 + config.quantum_radps**2 / 12)

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement:
        values = np.asarray(truth.wheel_speed_radps, dtype=float) + rng.normal(
            0.0, self._sigma, 4
        )
        values = _quantise(values, self._quantum)
        return Measurement(self.name, truth.t_s, self.names, values, self._covariance)


class HeadingSensor:
    """Dual-antenna GNSS heading with white Gaussian noise, wrapped to (-pi, pi]."""

    name = sensor_names.HEADING
    names = ("yaw_rad",)

    def __init__(self, config: HeadingConfig) -> None:
        self.period_s = config.period_s
        self._sigma = config.sigma_rad
        self._covariance = np.eye(1) * config.sigma_rad**2

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement:
        yaw = truth.yaw_rad + rng.normal(0.0, self._sigma)
        values = np.array([np.pi - np.mod(np.pi - yaw, 2.0 * np.pi)])
        return Measurement(self.name, truth.t_s, self.names, values, self._covariance)


class SteeringAngleSensor:
    """The steering-angle sensor, expressed as the mean front road-wheel angle."""

    name = sensor_names.STEERING
    names = ("steer_rad",)

    def __init__(self, config: SteeringConfig) -> None:
        self.period_s = config.period_s
        self._sigma = config.sigma_rad
        self._quantum = config.quantum_rad
        self._covariance = np.eye(1) * (config.sigma_rad**2 + config.quantum_rad**2 / 12)

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement:
        values = np.array([truth.steer_rad]) + rng.normal(0.0, self._sigma, 1)
        return Measurement(self.name, truth.t_s, self.names, _quantise(values, self._quantum),
                           self._covariance)


TRUTH_FIELDS = (
    "x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad", "vx_mps", "vy_mps",
    "yaw_rate_radps", "ax_mps2", "ay_mps2", "steer_rad",
)


class TruthSensor:
    """The true state as a noise-free measurement: feeds only the ``truth`` estimator."""

    name = sensor_names.TRUTH
    names = TRUTH_FIELDS

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self._covariance = np.zeros((len(TRUTH_FIELDS), len(TRUTH_FIELDS)))

    def sample(self, truth: VehicleState, rng: np.random.Generator) -> Measurement:
        del rng  # noise-free by definition
        values = np.array([getattr(truth, name) for name in TRUTH_FIELDS])
        return Measurement(self.name, truth.t_s, self.names, values, self._covariance)


def make_sensors(config: SensorsConfig) -> list[Sensor]:
    """The enabled sensors of the suite, in a fixed order."""
    sensors: list[Sensor] = []
    if config.gnss.enabled:
        sensors.append(GnssSensor(config.gnss))
    if config.gnss_velocity.enabled:
        sensors.append(GnssVelocitySensor(config.gnss_velocity))
    if config.heading.enabled:
        sensors.append(HeadingSensor(config.heading))
    if config.imu.enabled:
        sensors.append(ImuSensor(config.imu))
    if config.wheel_speed.enabled:
        sensors.append(WheelSpeedSensor(config.wheel_speed))
    if config.steering.enabled:
        sensors.append(SteeringAngleSensor(config.steering))
    return sensors
