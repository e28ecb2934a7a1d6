"""The debugging estimator hands the truth through."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cosim.core.initial_state import InitialState
from cosim.core.records import Measurement, VehicleState
from cosim.core.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.errors import TimeOrderError
from estimation.state import VEHICLE_STATE_NAMES
from estimation.truth import TRUTH_STATE_NAMES, TruthEstimator


def _truth(t_s: float, **changes: float) -> Measurement:
    """A truth measurement as the harness's truth sensor makes it: every scalar field."""
    state = VehicleState(
        t_s=t_s,
        x_m=10.0,
        y_m=-2.0,
        z_m=0.5,
        roll_rad=0.01,
        pitch_rad=-0.02,
        yaw_rad=0.5,
        vx_mps=15.0,
        vy_mps=0.2,
        yaw_rate_radps=0.1,
        ax_mps2=1.0,
        ay_mps2=1.5,
        steer_rad=0.03,
        wheel_speed_radps=(48.0, 48.0, 48.0, 48.0),
    )
    state = dataclasses.replace(state, **changes)
    names = tuple(
        f.name
        for f in dataclasses.fields(VehicleState)
        if f.name not in ("t_s", "wheel_speed_radps")
    )
    values = np.array([getattr(state, n) for n in names], dtype=float)
    return Measurement("truth", t_s, names, values, np.zeros((len(names), len(names))))


def _estimator() -> TruthEstimator:
    return TruthEstimator(
        EstimatorConfig(name="truth"), InitialState(speed_mps=12.0), VehicleParams()
    )


def test_names_extend_the_ekf_states() -> None:
    assert TRUTH_STATE_NAMES[: len(VEHICLE_STATE_NAMES)] == VEHICLE_STATE_NAMES
    assert "vy_mps" in TRUTH_STATE_NAMES and "steer_rad" in TRUTH_STATE_NAMES


def test_initial_estimate_before_any_truth() -> None:
    estimate = _estimator().estimate()
    assert estimate["vx_mps"] == 12.0 and estimate["x_m"] == 0.0


def test_truth_is_returned_with_zero_covariance() -> None:
    estimator = _estimator()
    result = estimator.update(_truth(0.5))
    assert result.accepted and result.nis == 0.0
    estimate = estimator.estimate()
    assert estimate.t_s == 0.5
    for name, value in (("x_m", 10.0), ("vy_mps", 0.2), ("steer_rad", 0.03), ("yaw_rad", 0.5)):
        assert estimate[name] == value
    np.testing.assert_array_equal(estimate.covariance, 0.0)


def test_other_sensors_are_ignored_not_rejected() -> None:
    estimator = _estimator()
    gnss = Measurement("gnss", 0.1, ("x_m", "y_m"), np.array([5.0, 5.0]), np.eye(2))
    result = estimator.update(gnss)
    assert not result.accepted and result.reason == "ignored"
    assert estimator.counts()["gnss"]["ignored"] == 1
    assert estimator.estimate()["x_m"] == 0.0


def test_non_finite_truth_is_rejected_and_counted() -> None:
    estimator = _estimator()
    estimator.update(_truth(0.1))
    result = estimator.update(_truth(0.2, x_m=math.nan))
    assert not result.accepted
    assert estimator.counts()["truth"]["rejected_nonfinite"] == 1
    assert np.isfinite(estimator.estimate().mean).all()


def test_predict_extrapolates_and_refuses_to_go_back() -> None:
    estimator = _estimator()
    estimator.update(_truth(1.0, yaw_rad=0.0, vy_mps=0.0, yaw_rate_radps=0.0, ay_mps2=0.0))
    estimator.predict(1.1)
    estimate = estimator.estimate()
    assert estimate.t_s == 1.1
    # 15 m/s accelerating at 1 m/s^2 for 0.1 s: 1.505 m, 15.1 m/s.
    assert estimate["x_m"] == pytest.approx(10.0 + 1.505)
    assert estimate["vx_mps"] == pytest.approx(15.1)
    assert estimate["y_m"] == pytest.approx(-2.0)
    with pytest.raises(TimeOrderError):
        estimator.predict(1.0)
