"""Estimators by name, and the sensors each one needs."""

from __future__ import annotations

import dataclasses
import typing

import pytest

from cosim.core.exceptions import ConfigError
from cosim.core.initial_state import InitialState
from cosim.core.vehicle_params import VehicleParams
from estimation.config import EstimatorConfig
from estimation.ekf import Ekf
from estimation.registry import (
    ESTIMATOR_NAMES,
    estimator_class,
    make_estimator,
    required_sensors,
    supported_sensors,
)
from estimation.truth import TruthEstimator
from estimation.ukf import Ukf


def test_every_built_in_name_is_registered() -> None:
    """``estimator.name`` takes the built-in names (plug-ins too, so the field has no fixed
    choices): each one builds and says which sensors it needs."""
    for name in ESTIMATOR_NAMES:
        assert EstimatorConfig(name=name).name == name
        assert estimator_class(name).required_sensors


@pytest.mark.parametrize(("name", "cls"), [("ekf", Ekf), ("ukf", Ukf), ("truth", TruthEstimator)])
def test_make_estimator(name: str, cls: type) -> None:
    estimator = make_estimator(
        EstimatorConfig(name=name), InitialState(x_m=2.0), VehicleParams(), t0_s=1.5
    )
    assert isinstance(estimator, cls)
    estimate = estimator.estimate()
    assert estimate.t_s == 1.5
    assert estimate["x_m"] == 2.0


def test_unknown_name_lists_the_known_ones() -> None:
    with pytest.raises(ConfigError, match="ekf, ukf, truth"):
        make_estimator(EstimatorConfig(name="magic"), InitialState(), VehicleParams())


def test_sensors_each_estimator_needs() -> None:
    for name in ("ekf", "ukf"):
        assert required_sensors(name) == ("gnss",)
        assert set(supported_sensors(name)) >= {"gnss", "imu", "wheel_speed", "steering"}
        assert "truth" not in supported_sensors(name)  # a filter never sees the truth
    assert required_sensors("truth") == ("truth",)
    for name in ESTIMATOR_NAMES:
        assert set(required_sensors(name)) <= set(supported_sensors(name))


def test_config_fields_carry_units_or_are_flags() -> None:
    """Every numeric key names its unit (or is a probability, a pure number)."""
    units = (
        "_m",
        "_rad",
        "_mps",
        "_radps",
        "_mps2",
        "_s",
        "_s3",
        "_s5pm2",
        "m2ps5",
        "rad2ps3",
        "m2ps3",
        "rad2ps",
        "m2ps",
        "1ps",
        "scale_sigma",
        "_radpmps2",
        "_hz",
        "_radpnm",
        "_mpn",
        "_1prad",
    )
    dimensionless = ("gate_probability", "roll_damping_ratio", "ukf_alpha", "ukf_beta",
                     "ukf_kappa", "lateral_residual_relative", "wheel_slip_per_force_ratio",
                     "ekf_linearisation_tolerance", "accel_command_relative_sigma",
                     "tyre_load_sensitivity_front", "tyre_load_sensitivity_rear",
                     "wheel_slip_peak_force_ratio", "wheel_slip_shape", "wheel_slip_curvature")
    hints = typing.get_type_hints(EstimatorConfig)
    for f in dataclasses.fields(EstimatorConfig):
        if hints[f.name] is float and f.name not in dimensionless:
            assert f.name.endswith(units), f.name
