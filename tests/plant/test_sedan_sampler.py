"""Sampled sedans: within the published ranges, for plant and belief alike, one per seed."""

from __future__ import annotations

import pytest

from cosim.core.vehicle_params import PlantConfig
from cosim.plant.sedan_sampler import RANGES, axle_cornering_stiffness_npr, sampled_sedan
from cosim.simulation.scenario_config import load_config


def test_the_nominal_sedans_belief_is_what_identification_found() -> None:
    plant = PlantConfig()
    front, rear = axle_cornering_stiffness_npr(plant, plant.tyre)
    assert front == pytest.approx(72550.0, rel=0.005)  # cosim identify on the nominal sedan
    assert rear == pytest.approx(79580.0, rel=0.005)


@pytest.mark.parametrize("index", range(900, 920))
def test_a_sampled_sedan_is_within_the_ranges(index: int) -> None:
    car = sampled_sedan(index)
    plant = car["plant"]
    assert RANGES["mass_kg"][0] <= plant["mass_kg"] <= RANGES["mass_kg"][1]
    wheelbase = plant["cog_front_m"] + plant["cog_rear_m"]
    assert RANGES["wheelbase_m"][0] - 1e-3 <= wheelbase <= RANGES["wheelbase_m"][1] + 1e-3
    share = plant["cog_rear_m"] / wheelbase
    assert RANGES["front_weight_share"][0] - 1e-3 <= share <= RANGES["front_weight_share"][1] + 1e-3
    index_of_inertia = plant["yaw_inertia_kgm2"] / (
        plant["mass_kg"] * plant["cog_front_m"] * plant["cog_rear_m"])
    low, high = RANGES["dynamic_index"]
    assert low - 1e-3 <= index_of_inertia <= high + 1e-3
    assert RANGES["tyre_friction"][0] <= plant["tyre_friction"] <= RANGES["tyre_friction"][1]
    model = car["tracker"]["model"]
    assert all(model[key] == value for key, value in plant.items() if key != "tyre")


def test_the_config_takes_the_sample_and_explicit_keys_win() -> None:
    config = load_config("lane-change", overrides=["vehicle_sample=3", "plant.mass_kg=1500"])
    car = sampled_sedan(3)
    assert config.plant.mass_kg == 1500.0
    assert config.tracker.model.mass_kg == car["tracker"]["model"]["mass_kg"]
    assert config.plant.cog_height_m == car["plant"]["cog_height_m"]
    assert sampled_sedan(3) == car and sampled_sedan(4) != car


def test_a_sampled_sedans_filter_is_told_its_tyres_and_roll() -> None:
    """The filter of a sampled sedan believes the car's data sheet (cosim/plant/data_sheet.py),
    not the nominal sedan's: its roll mode, its tyres' load sensitivity and relaxation at
    its axle loads, their peak on its road; an explicit key wins."""
    from cosim.plant.data_sheet import roll_belief, tyre_beliefs
    from estimation.config import EstimatorConfig

    config = load_config("lane-change", overrides=["vehicle_sample=3"])
    believed = config.estimator
    expected = {**roll_belief(config.plant),
                **tyre_beliefs(config.plant, config.plant.tyre_friction)}
    for name, value in expected.items():
        assert getattr(believed, name) == value, name
    nominal = EstimatorConfig()
    differs = [name for name in expected if getattr(nominal, name) != getattr(believed, name)]
    assert {"roll_gradient_radpmps2", "tyre_load_sensitivity_front",
            "tyre_relaxation_length_front_m", "wheel_slip_peak_force_ratio"} <= set(differs)
    told = load_config("lane-change", overrides=["vehicle_sample=3",
                                                 "estimator.roll_gradient_radpmps2=0.012"])
    assert told.estimator.roll_gradient_radpmps2 == 0.012


def test_a_sample_of_a_published_car_is_refused() -> None:
    """vehicle_sample draws sedans: with car: bmw-320i it would put the sample's mass and CoG
    on the BMW's tracks and tyres, a car neither is; one line naming both."""
    from cosim.core.exceptions import ConfigError

    with pytest.raises(ConfigError, match=r"vehicle_sample = 3 with car = 'bmw-320i'"):
        load_config("lane-change", overrides=["car=bmw-320i", "vehicle_sample=3"])
    assert load_config("lane-change", overrides=["car=sedan", "vehicle_sample=3"]).plant \
        .mass_kg == sampled_sedan(3)["plant"]["mass_kg"]
