"""The belief a car's data sheet gives (cosim/plant/data_sheet.py): the sedan's is
the filter's default belief; another car's carries its own figures, tyres, steering and roll."""

from __future__ import annotations

import dataclasses

import pytest

from cosim.core.suspension_params import SuspensionParams
from cosim.core.vehicle_params import PlantConfig, VehicleParams
from cosim.plant.data_sheet import data_sheet_belief
from cosim.plant.roll_mode import roll_mode
from cosim.plant.sedan_model import sedan_layout
from estimation.config import EstimatorConfig


def test_the_sedans_data_sheet_is_the_filters_default_belief() -> None:
    """Derived from the default plant, every estimator belief is the filter's default (which
    were derived by hand from the same car, some rounded), and no figure of the car differs
    from the controller's."""
    sheet = data_sheet_belief(PlantConfig(), VehicleParams(), fitted=())
    assert sheet.model == {}
    defaults = EstimatorConfig()
    assert set(sheet.estimator) == {
        "tyre_load_sensitivity_front", "tyre_load_sensitivity_rear",
        "tyre_relaxation_length_front_m", "tyre_relaxation_length_rear_m",
        "wheel_slip_peak_force_ratio", "wheel_slip_per_force_ratio",
        "wheel_slip_combined_stiffness_1prad", "wheel_slip_shape", "wheel_slip_curvature",
        "steering_compliance_radpnm",
        "roll_gradient_radpmps2", "roll_frequency_hz", "roll_damping_ratio"}
    for name, value in sheet.estimator.items():
        assert value == pytest.approx(getattr(defaults, name), rel=5e-3), name


def test_a_taller_heavier_car_has_its_own_figures_and_beliefs() -> None:
    """A van-like car (1,900 kg, CoG 0.75 m high, wider front track, softer springs: ride
    1.2 and 1.3 Hz, tyres stiffer in slip): its figures the fit does not hold are in the
    controller's belief, the fitted ones are left to the fit, the road's friction is not the
    car's; the filter's roll gradient is its body's, its tyres work nearer their peak
    stiffness under the heavier load (less load sensitivity), its slip curve is its tyre's."""
    sedan = PlantConfig()
    van = dataclasses.replace(
        sedan, mass_kg=1900.0, cog_height_m=0.75, track_front_m=1.62, tyre_friction=0.6,
        tyre=dataclasses.replace(sedan.tyre, slip_stiffness_per_load=25.0),
        suspension=dataclasses.replace(SuspensionParams(), ride_frequency_front_hz=1.2,
                                       ride_frequency_rear_hz=1.3))
    sheet = data_sheet_belief(van, VehicleParams(), fitted=("mass_kg",))
    assert sheet.model == {"track_front_m": 1.62, "cog_height_m": 0.75}
    base = data_sheet_belief(sedan, VehicleParams(), fitted=()).estimator
    mode = roll_mode(sedan_layout(van, van.suspension), van.suspension)
    assert sheet.estimator["roll_gradient_radpmps2"] == pytest.approx(mode.gradient_radpmps2,
                                                                      rel=5e-3)
    assert sheet.estimator["roll_gradient_radpmps2"] > 1.5 * base["roll_gradient_radpmps2"]
    assert sheet.estimator["roll_frequency_hz"] < base["roll_frequency_hz"]
    assert sheet.estimator["wheel_slip_peak_force_ratio"] == base["wheel_slip_peak_force_ratio"]
    assert sheet.estimator["wheel_slip_per_force_ratio"] == 1.0 / 25.0
    for axle in ("front", "rear"):
        assert (sheet.estimator[f"tyre_load_sensitivity_{axle}"]
                < base[f"tyre_load_sensitivity_{axle}"])
