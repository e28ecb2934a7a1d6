"""The plant and the sensors implement their protocols (:mod:`cosim.plant.protocol`,
:mod:`cosim.sensing.protocol`)."""

from __future__ import annotations

from cosim.core.initial_state import InitialState
from cosim.core.plugins import missing_members
from cosim.core.sensor_names import FUSED_SENSORS
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant
from cosim.plant.protocol import Plant
from cosim.sensing.protocol import Sensor
from cosim.sensing.sensors import TruthSensor, make_sensors
from cosim.simulation.scenario_config import load_config


def test_the_mujoco_plant_is_a_plant() -> None:
    plant = MujocoPlant(PlantConfig(), 0.002, InitialState(speed_mps=5.0))
    assert isinstance(plant, Plant)
    assert missing_members(MujocoPlant, Plant) == ["physics_dt_s", "mjcf_xml"]  # set in
    # __init__, so only an instance has them
    assert missing_members(plant, Plant) == []


def test_every_sensor_is_a_sensor() -> None:
    config = load_config("lane-change", overrides=[
        f"sensors.{name}.enabled=true" for name in FUSED_SENSORS])
    for sensor in [*make_sensors(config.sensors), TruthSensor(0.01)]:
        assert isinstance(sensor, Sensor), sensor.name
    assert not isinstance(object(), Sensor)
