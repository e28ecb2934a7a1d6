"""What the filters believe about their sensors' noise: ``estimator.noise``.

The sensors' true figures live in ``sensors.*`` (:mod:`cosim.sensing.sensors`) and make the
noise; the figures here make the filters' measurement covariance ``R`` and the random walks
of the bias states in ``Q``. They are two separate pieces of data, so a mismatch (a GNSS
receiver worse than its datasheet, an IMU whose bias wanders faster than believed) is a
configuration, not a code change: ``--set sensors.gnss.sigma_m=0.05 --set
estimator.noise.gnss_sigma_m=0.02``.

The defaults are datasheet-like figures of the ``rtk`` suite's parts (RTK-corrected GNSS,
an automotive MEMS IMU, ABS wheel encoders, an EPS steering-angle sensor) and so equal the
sensors' own defaults. A suite chosen with ``sensors.suite`` also sets the belief (the
same receiver class is believed to be what it is): :func:`suite_noise_preset`, applied by
:func:`cosim.simulation.scenario_config.load_config`; a figure set explicitly under
``estimator.noise`` wins. The ``ideal`` suite's sensors are noise-free, but a Kalman filter
cannot believe a zero covariance, so the belief keeps the ``rtk`` datasheet (the filter is
then under-confident, by design of that debugging suite).

Quantisation: a sensor that rounds to a step ``q`` adds an error uniform on
``[-q/2, q/2]``, of variance ``q^2 / 12`` (Widrow and Kollar, "Quantization Noise",
Cambridge University Press 2008, ch. 4); it is added to the white noise's variance.
Random walks are given as the standard deviation of the change over one second, the way
datasheets quote them (a bias instability's random walk, "per sqrt(s)"): the PSD that
drives the filter's bias state is its square.
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.config_fields import setting
from cosim.core.records import WHEEL_NAMES


@dataclass(frozen=True)
class NoiseBelief:
    """The filters' belief about their sensors (datasheet figures; see the module)."""

    gnss_sigma_m: float = setting(
        0.02, low=1e-6, high=100.0, doc="GNSS position, per horizontal axis (rtk: 2 cm)"
    )
    gnss_velocity_sigma_mps: float = setting(
        0.05, low=1e-6, high=10.0, doc="GNSS (Doppler) velocity, per horizontal axis"
    )
    heading_sigma_rad: float = setting(0.003, low=1e-7, high=1.0, doc="dual-antenna heading")
    gyro_sigma_radps: float = setting(0.005, low=1e-7, high=10.0, doc="yaw-rate white noise")
    gyro_bias_walk_radps: float = setting(
        0.0002, low=0.0, high=1.0, doc="gyro bias change per sqrt(s): the bias state's walk"
    )
    accel_sigma_mps2: float = setting(0.05, low=1e-7, high=100.0, doc="accelerometer noise")
    accel_bias_walk_mps2: float = setting(
        0.002, low=0.0, high=10.0, doc="ax bias change per sqrt(s): the bias state's walk"
    )
    wheel_sigma_radps: float = setting(0.05, low=1e-7, high=100.0, doc="wheel-speed noise")
    wheel_quantum_radps: float = setting(
        0.01, low=0.0, high=10.0, doc="wheel-speed resolution (adds q^2/12)"
    )
    steer_sigma_rad: float = setting(0.001, low=1e-7, high=1.0, doc="steering-angle noise")
    steer_quantum_rad: float = setting(
        0.0005, low=0.0, high=0.1, doc="steering-angle resolution (adds q^2/12)"
    )

    @property
    def gyro_bias_psd_rad2ps3(self) -> float:
        """PSD of the white noise driving the gyro-bias state [(rad/s)^2/s]."""
        return self.gyro_bias_walk_radps**2

    @property
    def accel_bias_psd_m2ps5(self) -> float:
        """PSD of the white noise driving the ax-bias state [(m/s^2)^2/s]."""
        return self.accel_bias_walk_mps2**2

    def channel_variances(self) -> dict[str, dict[str, float]]:
        """Believed variance of every channel the filters can fuse, by sensor and channel
        name (white noise plus quantisation)."""
        wheel = self.wheel_sigma_radps**2 + self.wheel_quantum_radps**2 / 12.0
        accel = self.accel_sigma_mps2**2
        return {
            "gnss": {"x_m": self.gnss_sigma_m**2, "y_m": self.gnss_sigma_m**2},
            "gnss_velocity": {
                "v_east_mps": self.gnss_velocity_sigma_mps**2,
                "v_north_mps": self.gnss_velocity_sigma_mps**2,
            },
            "heading": {"yaw_rad": self.heading_sigma_rad**2},
            "imu": {
                "yaw_rate_radps": self.gyro_sigma_radps**2,
                "ax_mps2": accel,
                "ay_mps2": accel,
            },
            "wheel_speed": {f"{w}_radps": wheel for w in WHEEL_NAMES},
            "steering": {
                "steer_rad": self.steer_sigma_rad**2 + self.steer_quantum_rad**2 / 12.0
            },
        }


def suite_noise_preset(suite: str) -> dict[str, float]:
    """The belief figures a sensor suite (``sensors.suite``) changes from the defaults, as
    an ``estimator.noise:`` mapping: ``gnss`` believes a standalone receiver (0.5 m); ``rtk``
    and ``ideal`` keep the datasheet defaults (see the module docstring)."""
    if suite == "gnss":
        return {"gnss_sigma_m": 0.5}
    return {}
