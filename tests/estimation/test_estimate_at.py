"""``estimate_at``: an observer's look at the belief between the filter's own steps."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.core.initial_state import InitialState
from cosim.core.records import Measurement
from cosim.core.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.registry import make_estimator


@pytest.mark.parametrize("name", ["ekf", "ukf", "truth"])
def test_a_look_changes_nothing_and_equals_the_prediction(name: str) -> None:
    def fresh():  # noqa: ANN202
        return make_estimator(EstimatorConfig(name=name), InitialState(speed_mps=15.0),
                              VehicleParams(), rng=np.random.default_rng(3))

    looked, plain = fresh(), fresh()
    seen = looked.estimate_at(0.013)
    assert looked.t_s == 0.0
    plain.predict(0.013)
    assert seen.t_s == pytest.approx(0.013)
    np.testing.assert_array_equal(seen.mean, plain.estimate().mean)
    np.testing.assert_array_equal(seen.covariance, plain.estimate().covariance)
    # The filter that was looked at goes on exactly as the one that was not.
    untouched = fresh()
    looked.predict(0.05)
    untouched.predict(0.05)
    np.testing.assert_array_equal(looked.estimate().mean, untouched.estimate().mean)
    np.testing.assert_array_equal(looked.estimate().covariance,
                                  untouched.estimate().covariance)


@pytest.mark.parametrize("name", ["ekf", "ukf"])
def test_the_looked_at_prediction_is_taken_only_from_the_same_belief(name: str) -> None:
    # A look at t, then the filter's own prediction to t: the look's arithmetic is reused
    # (the same numbers as predicting afresh). After an update in between (at the filter's
    # own time, so nothing was predicted on the way) it is not.
    def fresh():  # noqa: ANN202
        return make_estimator(EstimatorConfig(name=name), InitialState(speed_mps=15.0),
                              VehicleParams(), rng=np.random.default_rng(3))

    looked, plain = fresh(), fresh()
    for t_s in (0.01, 0.02, 0.03):
        seen = looked.estimate_at(t_s)
        looked.predict(t_s)
        plain.predict(t_s)
        assert looked.t_s == plain.t_s == t_s
        np.testing.assert_array_equal(looked.estimate().mean, seen.mean)
        np.testing.assert_array_equal(looked.estimate().mean, plain.estimate().mean)
        np.testing.assert_array_equal(looked.estimate().covariance,
                                      plain.estimate().covariance)
    looked.estimate_at(0.05)
    fix = Measurement("gnss", 0.03, ("x_m", "y_m"), np.array([0.9, 0.1]), 0.25 * np.eye(2))
    assert looked.update(fix).accepted and plain.update(fix).accepted
    looked.predict(0.05)  # from the updated belief: predicted afresh
    plain.predict(0.05)
    np.testing.assert_array_equal(looked.estimate().mean, plain.estimate().mean)
    np.testing.assert_array_equal(looked.estimate().covariance, plain.estimate().covariance)
