"""The car's static equilibrium, found once per process
(:func:`cosim.plant.car.static_equilibrium`): a plant that reuses it starts exactly as one
that let itself settle, and a car of other numbers settles anew."""

from __future__ import annotations

import dataclasses

from cosim.core.initial_state import InitialState
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant, static_equilibrium

DT_S = 0.002


def test_a_reused_equilibrium_is_the_one_the_car_settles_to() -> None:
    initial = InitialState(speed_mps=12.0)
    reused = MujocoPlant(PlantConfig(), DT_S, initial)
    settled = MujocoPlant(PlantConfig(), DT_S, initial, settle_here=True)
    assert reused.equilibrium == settled.equilibrium
    assert reused.equilibrium is static_equilibrium(PlantConfig(), DT_S, True)
    # One second coasting from the same start: the same car, bit for bit.
    reused.advance_steps(500)
    settled.advance_steps(500)
    assert reused.state() == settled.state()


def test_a_heavier_car_settles_lower_on_its_own() -> None:
    heavy = dataclasses.replace(PlantConfig(), mass_kg=1.3 * PlantConfig().mass_kg)
    light, loaded = static_equilibrium(PlantConfig(), DT_S, True), \
        MujocoPlant(heavy, DT_S, InitialState()).equilibrium
    assert loaded.z_m < light.z_m
    assert sum(loaded.static_load_n) > 1.2 * sum(light.static_load_n)
