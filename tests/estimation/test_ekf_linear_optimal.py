"""Where the EKF is the optimal (linear) Kalman filter, it must equal it.

Driving due east at constant speed with GNSS only, and every measurement error along x, the
filter's linearisation point never leaves yaw = yaw rate = vy = 0: the problem is linear and
time-invariant. Its reference solution is built here independently of estimation/models.py:
the continuous system matrix by hand, its discretisation over the GNSS period with
scipy.linalg.expm (Van Loan 1978 for the noise), the steady-state prior covariance from the
discrete algebraic Riccati equation, and the whole time history from filterpy's plain
KalmanFilter.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest
import scipy.linalg
from filterpy.kalman import KalmanFilter

from cosim.initial_state import InitialState
from cosim.records import Measurement
from cosim.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.ekf import Ekf
from estimation.models import STATE_NAMES, VEHICLE_STATE_NAMES

SPEED_MPS = 10.0
GNSS_PERIOD_S = 0.1
GNSS_SIGMA_M = 0.5
DURATION_S = 60.0
CONFIG = EstimatorConfig()
VEHICLE = [STATE_NAMES.index(n) for n in VEHICLE_STATE_NAMES]
"""Without wheel speeds the rolling-radius scale is unobservable (a constant random walk):
the reference is the vehicle states alone, compared with the EKF's block of them."""


def _index(name: str) -> int:
    """Position in the reference (vehicle states only)."""
    return VEHICLE_STATE_NAMES.index(name)


def _linear_reference() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Transition, process noise, measurement matrix and noise over one GNSS period."""
    n = len(VEHICLE_STATE_NAMES)
    a = np.zeros((n, n))
    # Linearised at yaw = 0, vx = SPEED_MPS, vy = yaw rate = ax = 0.
    a[_index("x_m"), _index("vx_mps")] = 1.0  # dx/dt = vx cos(yaw) - vy sin(yaw)
    a[_index("y_m"), _index("yaw_rad")] = SPEED_MPS  # dy/dt = vx sin(yaw) + vy cos(yaw)
    a[_index("y_m"), _index("vy_mps")] = 1.0
    a[_index("yaw_rad"), _index("yaw_rate_radps")] = 1.0
    a[_index("vx_mps"), _index("ax_mps2")] = 1.0  # dvx/dt = ax + r vy
    a[_index("vy_mps"), _index("vy_mps")] = -1.0 / CONFIG.lateral_velocity_time_constant_s
    psd = {
        "x_m": CONFIG.position_psd_m2ps,
        "y_m": CONFIG.position_psd_m2ps,
        "yaw_rad": CONFIG.yaw_psd_rad2ps,
        "vy_mps": CONFIG.lateral_accel_psd_m2ps3,
        "yaw_rate_radps": CONFIG.yaw_accel_psd_rad2ps3,
        "ax_mps2": CONFIG.jerk_psd_m2ps5,
    }
    w = np.diag([psd.get(name, 0.0) for name in VEHICLE_STATE_NAMES])
    block = np.zeros((2 * n, 2 * n))
    block[:n, :n] = -a
    block[:n, n:] = w
    block[n:, n:] = a.T
    exponential = scipy.linalg.expm(block * GNSS_PERIOD_S)
    transition = exponential[n:, n:].T
    q = transition @ exponential[:n, n:]
    h = np.zeros((2, n))
    h[0, _index("x_m")] = 1.0
    h[1, _index("y_m")] = 1.0
    r = np.eye(2) * GNSS_SIGMA_M**2
    return transition, 0.5 * (q + q.T), h, r


@dataclass
class _History:
    """EKF and reference KF side by side at every GNSS update."""

    ekf_priors: list[np.ndarray] = field(default_factory=list)
    kf_priors: list[np.ndarray] = field(default_factory=list)
    ekf_posteriors: list[np.ndarray] = field(default_factory=list)
    kf_posteriors: list[np.ndarray] = field(default_factory=list)
    ekf_means: list[np.ndarray] = field(default_factory=list)
    kf_means: list[np.ndarray] = field(default_factory=list)


def _run(noise_sigma_m: float, seed: int = 7) -> _History:
    """Drive east at constant speed; GNSS x off by N(0, noise_sigma_m), y exact.

    With noise, the speed estimate moves and with it the linearisation of the lateral
    channel (dy/dt depends on vx yaw), so only the noiseless run is linear in every state;
    the longitudinal channel (x, vx, ax) is linear in both.
    """
    transition, q, h, r = _linear_reference()
    initial = InitialState(speed_mps=SPEED_MPS)
    ekf = Ekf(CONFIG, initial, VehicleParams())
    kf = KalmanFilter(dim_x=len(VEHICLE_STATE_NAMES), dim_z=2)
    kf.x = ekf.estimate().mean[VEHICLE].reshape(-1, 1).copy()
    kf.P = ekf.estimate().covariance[np.ix_(VEHICLE, VEHICLE)].copy()
    kf.F, kf.Q, kf.H, kf.R = transition, q, h, r
    rng = np.random.default_rng(seed)
    history = _History()
    for k in range(1, round(DURATION_S / GNSS_PERIOD_S) + 1):
        t_s = k * GNSS_PERIOD_S
        z = np.array([SPEED_MPS * t_s + rng.normal(0.0, noise_sigma_m), 0.0])
        ekf.predict(t_s)
        kf.predict()
        history.ekf_priors.append(ekf.estimate().covariance[np.ix_(VEHICLE, VEHICLE)])
        history.kf_priors.append(kf.P.copy())
        result = ekf.update(Measurement("gnss", t_s, ("x_m", "y_m"), z, r))
        assert result.accepted
        kf.update(z)
        posterior = ekf.estimate()
        history.ekf_posteriors.append(posterior.covariance[np.ix_(VEHICLE, VEHICLE)])
        history.kf_posteriors.append(kf.P.copy())
        history.ekf_means.append(posterior.mean[VEHICLE])
        history.kf_means.append(kf.x.reshape(-1).copy())
    return history


LONGITUDINAL = [VEHICLE_STATE_NAMES.index(n) for n in ("x_m", "vx_mps", "ax_mps2")]


def test_ekf_equals_the_linear_kalman_filter_noiseless() -> None:
    """Exact data: the problem is linear in every state; same P as filterpy at every step."""
    history = _run(noise_sigma_m=0.0)
    for ekf_p, kf_p in zip(history.ekf_priors, history.kf_priors, strict=True):
        np.testing.assert_allclose(ekf_p, kf_p, rtol=1e-7, atol=1e-13)
    for ekf_p, kf_p in zip(history.ekf_posteriors, history.kf_posteriors, strict=True):
        np.testing.assert_allclose(ekf_p, kf_p, rtol=1e-7, atol=1e-13)


def test_ekf_equals_the_linear_kalman_filter_longitudinally() -> None:
    """Noisy x: same means as filterpy's KalmanFilter, same longitudinal covariance."""
    history = _run(noise_sigma_m=GNSS_SIGMA_M)
    block = np.ix_(LONGITUDINAL, LONGITUDINAL)
    for ekf_mean, kf_mean in zip(history.ekf_means, history.kf_means, strict=True):
        np.testing.assert_allclose(ekf_mean, kf_mean, rtol=0.0, atol=1e-9)
    for ekf_p, kf_p in zip(history.ekf_posteriors, history.kf_posteriors, strict=True):
        np.testing.assert_allclose(ekf_p[block], kf_p[block], rtol=1e-7, atol=1e-13)


def test_steady_state_covariance_solves_the_riccati_equation() -> None:
    transition, q, h, r = _linear_reference()
    riccati_prior = scipy.linalg.solve_discrete_are(transition.T, h.T, q, r)
    history = _run(noise_sigma_m=0.0)
    ekf_prior = history.ekf_priors[-1]
    for name in ("x_m", "y_m", "vx_mps", "yaw_rad"):
        i = _index(name)
        assert ekf_prior[i, i] == pytest.approx(riccati_prior[i, i], rel=1e-6), name
    np.testing.assert_allclose(ekf_prior, riccati_prior, rtol=1e-5, atol=1e-12)
    # The posterior position variance is below the measurement's: the filter averages.
    i = _index("x_m")
    assert history.ekf_posteriors[-1][i, i] < GNSS_SIGMA_M**2
