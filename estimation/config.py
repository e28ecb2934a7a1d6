"""Configuration of a state estimator: the ``estimator:`` section of a scenario.

Every key is a validated :func:`cosim.config_fields.setting`, so a scenario file or the
command line (``--set estimator.gate=false``, ``--set estimator.jerk_psd_m2ps5=10``) is
checked by :func:`cosim.config_fields.from_dict` and a bad value names its dotted key.

Process noise is given as continuous-time power spectral densities (PSD) of white noise
driving one state each; the filter integrates them over every prediction interval
(:mod:`estimation.models`), so the tuning does not depend on the sensor rates. A PSD ``q``
driving a state makes that state a random walk whose standard deviation grows as
``sqrt(q * t)``. Units: ``m2ps5`` is m^2/s^5 (jerk), ``rad2ps3`` rad^2/s^3 (yaw
acceleration), ``m2ps3`` m^2/s^3 (lateral acceleration), ``rad2ps`` rad^2/s, ``m2ps`` m^2/s,
``1ps`` 1/s (a dimensionless state: the rolling-radius scale).
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.config_fields import setting

ESTIMATOR_NAMES: tuple[str, ...] = ("ekf", "truth")
"""Values ``estimator.name`` accepts; :func:`estimation.registry.make_estimator` builds each."""


@dataclass(frozen=True)
class EstimatorConfig:
    """The state estimator: which one, its process noise, initial uncertainty and gating."""

    name: str = setting(
        "ekf", choices=ESTIMATOR_NAMES, doc="ekf: the CTRA extended Kalman filter; truth: debug"
    )

    # Process noise (continuous-time white-noise PSDs).
    jerk_psd_m2ps5: float = setting(
        100.0, low=0.0, high=1e6, doc="longitudinal jerk driving ax_mps2 [m^2/s^5]"
    )
    yaw_accel_psd_rad2ps3: float = setting(
        0.5, low=0.0, high=1e6, doc="yaw acceleration driving yaw_rate_radps [rad^2/s^3]"
    )
    lateral_accel_psd_m2ps3: float = setting(
        0.3, low=0.0, high=1e6, doc="white lateral acceleration driving vy_mps [m^2/s^3]"
    )
    lateral_velocity_time_constant_s: float = setting(
        1.0, low=0.1, high=1e4, doc="vy_mps relaxes to zero with this time constant"
    )
    yaw_psd_rad2ps: float = setting(
        1e-6, low=0.0, high=10.0, doc="heading random walk (unmodelled yaw errors) [rad^2/s]"
    )
    position_psd_m2ps: float = setting(
        1e-4, low=0.0, high=100.0, doc="position random walk (unmodelled motion) [m^2/s]"
    )
    rolling_radius_scale_psd_1ps: float = setting(
        1e-6, low=0.0, high=1.0, doc="random walk of rolling_radius_scale (drive slip) [1/s]"
    )
    max_step_s: float = setting(
        0.01, low=1e-4, high=0.02, doc="longest sub-step of a prediction interval"
    )

    # Model errors of the measurement equations, added to each measurement's own covariance.
    wheel_model_sigma_mps: float = setting(
        0.05, low=0.0, high=10.0, doc="tyre slip, rolling-radius error (at the wheel centre)"
    )
    lateral_accel_model_sigma_mps2: float = setting(
        1.0, low=0.0, high=50.0, doc="ay = yaw_rate * vx neglects dvy/dt"
    )

    # Initial uncertainty (the mean comes from the scenario's initial state).
    init_position_sigma_m: float = setting(0.5, low=1e-6, high=1e4)
    init_yaw_sigma_rad: float = setting(0.05, low=1e-6, high=10.0)
    init_speed_sigma_mps: float = setting(0.5, low=1e-6, high=100.0)
    init_lateral_speed_sigma_mps: float = setting(0.1, low=1e-6, high=100.0)
    init_yaw_rate_sigma_radps: float = setting(0.05, low=1e-6, high=10.0)
    init_accel_sigma_mps2: float = setting(0.5, low=1e-6, high=100.0)
    init_rolling_radius_scale_sigma: float = setting(
        0.01, low=1e-6, high=0.5, doc="relative error of the believed wheel radius"
    )

    # Outlier rejection.
    gate: bool = setting(True, doc="reject updates whose NIS exceeds the chi-square gate")
    gate_probability: float = setting(
        0.9999, low=0.5, high=0.999999999, doc="chi-square probability of the NIS gate"
    )
    gate_release_s: float = setting(
        2.0,
        low=0.0,
        high=1e9,
        doc="after a sensor's updates fail the gate for this long, fuse them ungated",
    )
