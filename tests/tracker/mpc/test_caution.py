"""Caution (tracker/mpc/caution.py): the NMPCs' steering-rate weight grows with the
estimate's uncertainty across the car, so the wheel does not chase a converging estimate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.core.records import Estimate
from cosim.simulation.runner import run_unlogged
from cosim.simulation.scenario_config import load_config
from tracker.mpc.caution import lateral_variance_m2, steer_rate_factor

NAMES = ("x_m", "y_m", "yaw_rad", "vx_mps")


def _estimate(yaw_rad: float, covariance_xy: np.ndarray, names: tuple[str, ...] = NAMES
              ) -> Estimate:
    covariance = np.eye(len(names)) * 1e-4
    if "x_m" in names and "y_m" in names:
        xy = [names.index("x_m"), names.index("y_m")]
        covariance[np.ix_(xy, xy)] = covariance_xy
    mean = np.zeros(len(names))
    if "yaw_rad" in names:
        mean[names.index("yaw_rad")] = yaw_rad
    return Estimate(0.0, names, mean, covariance)


def test_the_variance_is_the_one_across_the_heading() -> None:
    # 2 m along x, 1 m along y, correlated: heading east the lateral variance is P_yy,
    # heading north P_xx, at 45 deg (P_xx + P_yy) / 2 - P_xy.
    covariance = np.array([[4.0, 0.5], [0.5, 1.0]])
    assert lateral_variance_m2(_estimate(0.0, covariance)) == pytest.approx(1.0)
    assert lateral_variance_m2(_estimate(math.pi / 2, covariance)) == pytest.approx(4.0)
    assert lateral_variance_m2(_estimate(math.pi / 4, covariance)) == pytest.approx(2.0)
    assert lateral_variance_m2(_estimate(-math.pi, covariance)) == pytest.approx(1.0)


def test_the_factor_is_one_plus_the_variance_over_sigma_0_squared() -> None:
    covariance = np.diag([4.0, 0.01])
    estimate = _estimate(0.0, covariance)
    assert steer_rate_factor(estimate, 0.1) == pytest.approx(2.0)
    assert steer_rate_factor(estimate, 0.05) == pytest.approx(5.0)
    assert steer_rate_factor(estimate, 0.0) == 1.0  # off
    # Nothing to be cautious about, or a covariance that says nothing: the weight as set.
    assert steer_rate_factor(_estimate(0.0, covariance, ("vx_mps", "yaw_rad")), 0.1) == 1.0
    broken = _estimate(0.0, np.array([[np.nan, 0.0], [0.0, np.nan]]))
    assert steer_rate_factor(broken, 0.1) == 1.0


@pytest.mark.slow
@pytest.mark.parametrize("tracker", ["dynamic-nmpc", "ltv-mpc"])
def test_a_receiver_without_rtk_no_longer_spins_the_fast_wheel(tracker: str) -> None:
    """The ``gnss`` suite (metre-class fixes, no Doppler velocity): the filter starts half a
    metre unsure and stays some 0.18 m unsure across the car. The fast wheel of the
    dynamic-bicycle trackers (their own ``steer_rate``, 0.3) chases the converging estimate
    into a growing oscillation: on this seed the LTV-MPC spins the car at 2.25 s (yaw rate
    swinging +-1 rad/s), as the NMPC did before its tyres saturated in its model
    (``tracker.grip.saturating_tyres``); the NMPC now slides without spinning (side slip
    3.2 m/s, heading error 0.20 rad, the wheel at 0.21 rad). With the caution's weight (about
    3 on this suite, 0.3 with RTK) each drives the lane change with half the heading error
    and half the steering (0.10 rad each): the NMPC takes it among the NLP's parameters,
    the LTV-MPC's QP as its own."""
    overrides = ["sensors.suite=gnss"]
    config = load_config("lane-change", seed=611, duration_s=6.0, tracker=tracker,
                         overrides=overrides)
    assert config.tracker.weights.steer_rate == 0.3
    assert config.tracker.caution_lateral_sigma_m > 0.0  # the default is cautious
    cautious = run_unlogged(config).metrics
    assert cautious["outcome"] == "ok", cautious["outcome"]
    careless = run_unlogged(load_config(
        "lane-change", seed=611, duration_s=6.0, tracker=tracker,
        overrides=[*overrides, "tracker.caution_lateral_sigma_m=0"])).metrics
    for key in ("heading_err_max_rad", "steer_max_rad"):
        assert careless[key] > 1.5 * cautious[key], (key, careless[key], cautious[key])
