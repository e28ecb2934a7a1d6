"""The filters' initial estimate: ``estimator.initial``.

A filter's prior ``N(x0_hat, P0)`` claims that the error ``x0 - x0_hat`` is distributed as
``N(0, P0)``. Starting the mean at the true initial state makes the error zero while P0
claims otherwise: convergence is never exercised and the early NEES is flattering. So the
mean is drawn, as the definition of a consistent prior requires (Bar-Shalom, Li,
Kirubarajan, "Estimation with Applications to Tracking and Navigation", Wiley 2001,
section 5.4.1: the initial estimate of a Monte Carlo run is drawn around the truth with the
initial covariance):

- ``sampled`` (the default): ``x0_hat = x0 + L n``, ``L L' = P0``, ``n ~ N(0, I)`` drawn
  from a generator the runner spawns from the run's seed for this purpose alone (so the
  sensors' and disturbances' noise is the same whatever the mode);
- ``first-fix``: sampled, then, at the first GNSS fix, the position is replaced by the
  fix and its covariance by the believed GNSS noise (a receiver's cold start;
  :class:`estimation.fusion.KalmanFusion`);
- ``truth``: the mean is the true initial state (debugging only).

The states of the car's motion (:data:`estimation.state.VEHICLE_STATE_NAMES`, the roll
rate and the steering rate) are sampled. The sensor states (gyro and accelerometer biases,
the rolling-radius and track scales) keep their nominal means (zero, one): their truth is
itself unknown (a sensor's turn-on bias is drawn by the sensor, the effective radius is the
tyre's), so the nominal
mean with its P0 is already the honest prior. The lateral residual is a model state with
no truth to centre on.
"""

from __future__ import annotations

import numpy as np

from cosim.core.initial_state import InitialState
from estimation.config import EstimatorConfig
from estimation.state import STATE_NAMES, VEHICLE_STATE_NAMES, wrap_angle

SAMPLED_STATES: tuple[str, ...] = (*VEHICLE_STATE_NAMES, "roll_rate_radps", "steer_rate_radps")
"""States whose initial mean is drawn around the truth in the ``sampled`` mode."""


def nominal_belief(
    config: EstimatorConfig, initial: InitialState
) -> tuple[np.ndarray, np.ndarray]:
    """The prior centred on ``initial`` (position, yaw, forward speed; the rest zero, the
    rolling-radius scale one) and its diagonal covariance P0 (the configured ``init_*``
    standard deviations)."""
    mean = {
        "x_m": initial.x_m,
        "y_m": initial.y_m,
        "yaw_rad": wrap_angle(initial.yaw_rad),
        "vx_mps": initial.speed_mps,
        "vy_mps": 0.0,
        "yaw_rate_radps": 0.0,
        "ax_mps2": 0.0,
        "steer_rad": 0.0,
        "steer_rate_radps": 0.0,
        "roll_rad": 0.0,
        "roll_rate_radps": 0.0,
        "lateral_accel_residual_mps2": 0.0,
        "gyro_bias_radps": 0.0,
        "ax_bias_mps2": 0.0,
        "ay_bias_mps2": 0.0,
        "rolling_radius_scale": 1.0,
        "wheel_track_scale": 1.0,
    }
    sigma = {
        "x_m": config.init_position_sigma_m,
        "y_m": config.init_position_sigma_m,
        "yaw_rad": config.init_yaw_sigma_rad,
        "vx_mps": config.init_speed_sigma_mps,
        "vy_mps": config.init_lateral_speed_sigma_mps,
        "yaw_rate_radps": config.init_yaw_rate_sigma_radps,
        "ax_mps2": config.init_accel_sigma_mps2,
        "steer_rad": config.init_steer_sigma_rad,
        "steer_rate_radps": config.init_steer_rate_sigma_radps,
        "roll_rad": config.init_roll_sigma_rad,
        "roll_rate_radps": config.init_roll_rate_sigma_radps,
        "lateral_accel_residual_mps2": config.lateral_residual_sigma_mps2,
        "gyro_bias_radps": config.init_gyro_bias_sigma_radps,
        "ax_bias_mps2": config.init_accel_bias_sigma_mps2,
        "ay_bias_mps2": config.init_accel_bias_sigma_mps2,
        "rolling_radius_scale": config.init_rolling_radius_scale_sigma,
        "wheel_track_scale": config.init_wheel_track_scale_sigma,
    }
    return (
        np.array([float(mean[name]) for name in STATE_NAMES]),
        np.diag([float(sigma[name]) ** 2 for name in STATE_NAMES]),
    )


def initial_belief(
    config: EstimatorConfig,
    initial: InitialState,
    rng: np.random.Generator | None,
) -> tuple[np.ndarray, np.ndarray]:
    """The filter's prior mean and covariance for ``config.initial``.

    ``initial`` is the car's true initial state; ``rng`` the generator of the draw. Without
    a generator the mean is ``initial`` itself whatever the mode: that is how a unit test
    states a prior; a run always passes one (:mod:`cosim.simulation.runner`).
    """
    mean, covariance = nominal_belief(config, initial)
    if rng is None or config.initial == "truth":
        return mean, covariance
    index = [STATE_NAMES.index(name) for name in SAMPLED_STATES]
    sigma = np.sqrt(np.diag(covariance)[index])
    mean[index] = mean[index] + sigma * rng.standard_normal(len(index))
    yaw = STATE_NAMES.index("yaw_rad")
    mean[yaw] = wrap_angle(float(mean[yaw]))
    return mean, covariance
