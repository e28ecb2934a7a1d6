"""The filters' process-model parameters from their configuration and the vehicle belief:
the process noise's power spectral densities, the body-roll mode and the bicycle
(:mod:`estimation.process_model`, :mod:`estimation.bicycle`)."""

from __future__ import annotations

import dataclasses

from cosim.core.vehicle_params import VehicleParams
from estimation.bicycle import BicycleParams, RollParams
from estimation.config import EstimatorConfig
from estimation.process_model import ProcessNoise
from estimation.steering_model import MIN_TIME_CONSTANT_S


def process_noise(config: EstimatorConfig) -> ProcessNoise:
    """The configured PSDs; the lateral residual's from its stationary sigma and time
    constant (a first-order Gauss-Markov process: ``q = 2 sigma^2 / tau``); the bias walks
    from the sensor belief ``config.noise``."""
    residual_psd = (
        2.0 * config.lateral_residual_sigma_mps2**2 / config.lateral_residual_time_constant_s
    )
    return ProcessNoise(
        position_psd_m2ps=config.position_psd_m2ps,
        yaw_psd_rad2ps=config.yaw_psd_rad2ps,
        lateral_accel_psd_m2ps3=config.lateral_accel_psd_m2ps3,
        yaw_accel_psd_rad2ps3=config.yaw_accel_psd_rad2ps3,
        jerk_psd_m2ps5=config.jerk_psd_m2ps5,
        steer_psd_rad2ps=config.steer_psd_rad2ps,
        steer_rate_psd_rad2ps3=config.steer_rate_psd_rad2ps3,
        roll_accel_psd_rad2ps3=config.roll_accel_psd_rad2ps3,
        lateral_residual_psd_m2ps5=residual_psd,
        gyro_bias_psd_rad2ps3=config.noise.gyro_bias_psd_rad2ps3,
        accel_bias_psd_m2ps5=config.noise.accel_bias_psd_m2ps5,
        rolling_radius_scale_psd_1ps=config.rolling_radius_scale_psd_1ps,
        wheel_track_scale_psd_1ps=config.wheel_track_scale_psd_1ps,
        lateral_residual_relative_psd_1ps=(
            2.0 * config.lateral_residual_relative**2 / config.lateral_residual_time_constant_s
        ),
        yaw_transient_psd_s3=config.yaw_transient_psd_s3,
        roll_accel_relative_psd_s=config.roll_accel_relative_psd_s,
        yaw_moment_relative_psd_s=config.yaw_moment_relative_psd_s,
        yaw_moment_load_transfer_psd_s5pm2=config.yaw_moment_load_transfer_psd_s5pm2,
        jerk_relative_psd_1ps=config.jerk_relative_psd_1ps,
    )


def told_process_noise(config: EstimatorConfig, untold: ProcessNoise, *, steering: bool,
                       accel: bool, steer_lag_s: float) -> ProcessNoise:
    """``untold`` (:func:`process_noise`) once the filter is told the controller's commands:
    told the steering commands, the steering's PSD is what the actuator does that its
    commands do not explain (``steer_commanded_psd_rad2ps``: :mod:`estimation.steering_model`
    follows the rest), growing with the steering rate by ``2 t^2 / tau`` for an actuator
    whose timing is known to ``t`` (``steer_commanded_timing_s``) and whose lag is
    ``steer_lag_s``; told the acceleration commands, the jerk's is what the drive does
    that they do not (``accel_commanded_jerk_psd_m2ps5``, with no part relative to the
    acceleration: :mod:`estimation.accel_commands` moves it). A filter told nothing keeps
    the random walks' larger PSDs, which must follow the whole motion alone."""
    changes: dict[str, float] = {}
    if steering:
        lag_s = max(steer_lag_s, MIN_TIME_CONSTANT_S)
        changes.update(steer_psd_rad2ps=config.steer_commanded_psd_rad2ps,
                       steer_rate_relative_psd_s=2.0 * config.steer_commanded_timing_s**2
                       / lag_s)
    if accel:
        changes.update(jerk_psd_m2ps5=config.accel_commanded_jerk_psd_m2ps5,
                       jerk_relative_psd_1ps=0.0)
    return dataclasses.replace(untold, **changes)


def roll_params(config: EstimatorConfig, belief: VehicleParams) -> RollParams:
    """The configured roll mode; the CoG sits the belief's ``cog_height_m`` above the roll
    axis (taken at the ground: independent vertical suspensions)."""
    return RollParams(
        gradient_radpmps2=config.roll_gradient_radpmps2,
        frequency_hz=config.roll_frequency_hz,
        damping_ratio=config.roll_damping_ratio,
        sway_arm_m=belief.cog_height_m if config.roll_gradient_radpmps2 > 0.0 else 0.0,
    )


def bicycle_params(config: EstimatorConfig, belief: VehicleParams) -> BicycleParams:
    """The bicycle the filters believe: ``belief``'s numbers with the configured tyre law,
    roll mode (:func:`roll_params`), load sensitivities and relaxation lengths."""
    return BicycleParams.from_vehicle(
        belief, config.tyre_model, roll_params(config, belief),
        load_sensitivity=config.tyre_load_sensitivities,
        relaxation_lengths_m=config.tyre_relaxation_lengths_m,
        lateral_transfer=config.lateral_load_transfer,
    )
