"""``estimate_at``: an observer's look at the belief between the filter's own steps."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.core.initial_state import InitialState
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
