"""Every built-in estimator implements :class:`estimation.protocol.Estimator`, and the
optional capabilities the runner checks for are the ones each one has."""

from __future__ import annotations

import pytest

from cosim.core.initial_state import InitialState
from cosim.core.plugins import missing_members
from cosim.core.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.protocol import CountsUpdates, Estimator, JointUpdater
from estimation.registry import make_estimator


@pytest.mark.parametrize(("name", "joint"), [("ekf", True), ("ukf", True), ("truth", False)])
def test_built_in_estimators_implement_the_protocol(name: str, joint: bool) -> None:
    estimator = make_estimator(EstimatorConfig(name=name), InitialState(), VehicleParams())
    assert isinstance(estimator, Estimator)
    assert isinstance(estimator, CountsUpdates)
    assert isinstance(estimator, JointUpdater) is joint
    assert missing_members(type(estimator), Estimator) == []


def test_a_class_without_the_methods_is_not_an_estimator() -> None:
    class OnlyEstimate:
        supported_sensors = ("gnss",)

        def estimate(self) -> None: ...

    assert not isinstance(OnlyEstimate(), Estimator)
    assert not isinstance(OnlyEstimate(), JointUpdater)
    assert missing_members(OnlyEstimate, Estimator) == ["predict", "update",
                                                        "required_sensors"]
