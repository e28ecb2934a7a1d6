"""What a run builds from its configuration alone (the MPC's model, the tyres' function,
the car's MJCF) is built once per process and shared by the runs after it; what a run
changes (buffers, the assets it is handed) stays its own."""

from __future__ import annotations

from cosim.plant.sedan_model import sedan_xml_and_assets
from cosim.plant.tyre_patches import tyre_patches_function
from cosim.simulation.scenario_config import load_config
from tracker.mpc.dynamic_nmpc import dynamic_model


def test_the_mpc_model_is_built_once_for_equal_settings() -> None:
    config = load_config("lane-change").tracker
    again = load_config("lane-change").tracker
    assert again is not config and again == config
    assert dynamic_model(again) is dynamic_model(config)
    other = load_config("lane-change", overrides=["tracker.model.mass_kg=1400"]).tracker
    assert dynamic_model(other) is not dynamic_model(config)
    assert dynamic_model(other).belief != dynamic_model(config).belief


def test_the_tyres_function_is_built_once_per_structure() -> None:
    assert tyre_patches_function(0.002, [1, 2, 3, 4], 0, 9) is \
        tyre_patches_function(0.002, (1, 2, 3, 4), 0, 9)
    assert tyre_patches_function(0.001, [1, 2, 3, 4], 0, 9) is not \
        tyre_patches_function(0.002, [1, 2, 3, 4], 0, 9)


def test_each_caller_gets_the_car_and_assets_of_its_own() -> None:
    plant = load_config("lane-change").plant
    xml, assets = sedan_xml_and_assets(plant, 0.002)
    assets["added.png"] = b"x"  # a caller that changes what it was handed changes no other's
    xml_again, assets_again = sedan_xml_and_assets(plant, 0.002)
    assert xml_again == xml and "added.png" not in assets_again
    heavier = load_config("lane-change", overrides=["plant.mass_kg=1800"]).plant
    assert sedan_xml_and_assets(heavier, 0.002)[0] != xml
