"""Sensor names come from one place (:mod:`cosim.core.sensor_names`): the sensors, their
config sections, the faults, the estimator's models and noise belief all agree with it."""

from __future__ import annotations

import dataclasses

from cosim.core.sensor_names import FUSED_SENSORS, RADAR, SENSOR_NAMES, TRUTH
from cosim.core.vehicle_params import VehicleParams
from cosim.sensing.faults import FAULT_SENSORS
from cosim.sensing.range_sensor import RangeSensor
from cosim.sensing.sensors import SensorsConfig, TruthSensor, make_sensors
from cosim.simulation.scenario_config import load_config
from estimation.fusion import KalmanFusion
from estimation.measurement_models import build_measurement_models
from estimation.noise_config import NoiseBelief


def test_every_sensor_of_a_full_suite_is_named_from_the_table() -> None:
    config = load_config("lane-change", overrides=[
        f"sensors.{name}.enabled=true" for name in FUSED_SENSORS])
    assert tuple(s.name for s in make_sensors(config.sensors)) == FUSED_SENSORS
    assert TruthSensor(0.01).name == TRUTH
    assert RangeSensor.name == RADAR
    assert set(SENSOR_NAMES) == {*FUSED_SENSORS, RADAR, TRUTH}


def test_config_sections_faults_and_estimator_agree_with_the_table() -> None:
    sections = {f.name for f in dataclasses.fields(SensorsConfig)} - {"suite"}
    assert sections == {*FUSED_SENSORS, RADAR}
    assert set(FAULT_SENSORS) == set(FUSED_SENSORS)
    assert set(KalmanFusion.supported_sensors) == set(FUSED_SENSORS)
    assert set(NoiseBelief().channel_variances()) == set(FUSED_SENSORS)
    models = build_measurement_models(VehicleParams(), 0.1, 0.1)
    assert set(models) == set(FUSED_SENSORS)
