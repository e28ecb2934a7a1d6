"""Conformance of the model as data: deterministic, and every element named.

After dm_control's ``suite_test`` (``test_environment_is_deterministic``,
``test_components_have_names``), for both tyre models and with the lead car.
"""

from __future__ import annotations

import math

import mujoco
import pytest

from cosim.core.initial_state import InitialState
from cosim.core.records import VehicleState
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant
from cosim.plant.traffic import Traffic, TrafficCarConfig
from tests.conformance.driving import DT_S, drive, plant_at, speed_loop

pytestmark = pytest.mark.conformance

TYRE_MODELS = ("pacejka", "contact")

NAMED_OBJECTS = (
    (mujoco.mjtObj.mjOBJ_BODY, "nbody"),
    (mujoco.mjtObj.mjOBJ_JOINT, "njnt"),
    (mujoco.mjtObj.mjOBJ_GEOM, "ngeom"),
    (mujoco.mjtObj.mjOBJ_SITE, "nsite"),
    (mujoco.mjtObj.mjOBJ_CAMERA, "ncam"),
    (mujoco.mjtObj.mjOBJ_LIGHT, "nlight"),
    (mujoco.mjtObj.mjOBJ_MATERIAL, "nmat"),
    (mujoco.mjtObj.mjOBJ_TEXTURE, "ntex"),
    (mujoco.mjtObj.mjOBJ_ACTUATOR, "nu"),
    (mujoco.mjtObj.mjOBJ_SENSOR, "nsensor"),
)


def slalom(config: PlantConfig) -> list[VehicleState]:
    """3 s at 15 m/s, steering a 0.1 rad, 1 Hz sine: tyres in their nonlinear range."""
    return drive(plant_at(15.0, config), 3.0,
                 speed_loop(config, 15.0, lambda t: 0.1 * math.sin(2.0 * math.pi * t)))


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
def test_two_plants_with_one_config_are_bit_identical(tyre_model: str) -> None:
    config = PlantConfig(tyre_model=tyre_model)
    first, second = slalom(config), slalom(config)
    assert first == second
    assert first[-1].t_s == pytest.approx(3.0)
    assert abs(first[-1].y_m) > 0.1  # it did slalom


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
@pytest.mark.parametrize("with_traffic", [False, True])
def test_every_element_is_named(tyre_model: str, with_traffic: bool) -> None:
    traffic = Traffic((("lead", TrafficCarConfig()),), InitialState()) if with_traffic \
        else None
    plant = MujocoPlant(PlantConfig(tyre_model=tyre_model), DT_S, InitialState(),
                        traffic=traffic)
    model = plant.model
    for kind, size_field in NAMED_OBJECTS:
        first = 1 if kind == mujoco.mjtObj.mjOBJ_BODY else 0  # body 0 is MuJoCo's world
        for index in range(first, getattr(model, size_field)):
            assert mujoco.mj_id2name(model, kind, index), f"unnamed {kind.name} {index}"
    assert (model.nmocap == 1) == with_traffic
