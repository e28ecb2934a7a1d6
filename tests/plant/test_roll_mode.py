"""The body's roll mode from the plant's numbers (cosim/plant/roll_mode.py): the sedan's is
the filter's default belief, each published car's belief carries its own, and the MuJoCo
plant rolls by the gradient it gives."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from cosim.core.suspension_params import SuspensionParams
from cosim.core.vehicle_params import PlantConfig
from cosim.log.reader import iter_messages
from cosim.plant.roll_mode import roll_mode
from cosim.plant.sedan_model import sedan_layout
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from estimation.config import EstimatorConfig

PUBLISHED = ("ford-escort", "bmw-320i", "vw-vanagon")


def _mode_of(plant: PlantConfig):
    return roll_mode(sedan_layout(plant, plant.suspension), plant.suspension)


def test_the_sedans_roll_mode_is_the_filters_default_belief() -> None:
    """The defaults of ``estimator.roll_*`` were derived by hand from the sedan's suspension
    (estimation/config.py): the function gives them to their printed digits."""
    mode, default = _mode_of(PlantConfig()), EstimatorConfig()
    assert mode.gradient_radpmps2 == pytest.approx(default.roll_gradient_radpmps2, abs=5e-5)
    assert mode.frequency_hz == pytest.approx(default.roll_frequency_hz, abs=5e-3)
    assert mode.damping_ratio == pytest.approx(default.roll_damping_ratio, abs=5e-3)


def test_anti_roll_bars_stiffen_and_soft_springs_are_refused() -> None:
    plant = PlantConfig()
    bars = dataclasses.replace(plant, suspension=SuspensionParams(
        anti_roll_stiffness_front_nmprad=30000.0, anti_roll_stiffness_rear_nmprad=10000.0))
    stiff, base = _mode_of(bars), _mode_of(plant)
    # K 84 310 -> 124 310 N m/rad: the gradient by their ratio, the frequency by its root
    assert stiff.gradient_radpmps2 == pytest.approx(base.gradient_radpmps2 * 84310 / 124310,
                                                    rel=2e-3)
    assert stiff.frequency_hz == pytest.approx(base.frequency_hz * (124310 / 84310) ** 0.5,
                                               rel=2e-3)
    soft = dataclasses.replace(plant, suspension=SuspensionParams(
        ride_frequency_front_hz=0.3, ride_frequency_rear_hz=0.3))
    with pytest.raises(ValueError, match="roll stiffness less its weight's lean"):
        _mode_of(soft)


@pytest.mark.parametrize("car", PUBLISHED)
def test_each_published_cars_belief_carries_its_roll_mode(car: str) -> None:
    """The belief file (written by tools/commonroad_cars.py) holds the roll mode of the car's
    own plant, not the sedan's."""
    config = load_config("lane-change", overrides=[f"car={car}"])
    mode = _mode_of(config.plant)
    belief = config.estimator
    assert belief.roll_gradient_radpmps2 == pytest.approx(mode.gradient_radpmps2, rel=5e-3)
    assert belief.roll_frequency_hz == pytest.approx(mode.frequency_hz, rel=5e-3)
    assert belief.roll_damping_ratio == pytest.approx(mode.damping_ratio, abs=5e-3)
    assert belief.roll_gradient_radpmps2 > 1.3 * EstimatorConfig().roll_gradient_radpmps2


@pytest.mark.slow
def test_the_plant_rolls_by_the_gradient_on_a_steady_circle(tmp_path: Path) -> None:
    """The VW Vanagon (CoG 0.75 m high) on the 40 m circle at 12 m/s (0.36 g): its steady
    roll per lateral acceleration in MuJoCo is the roll mode's gradient (0.0145 against
    0.0149 rad/(m/s^2)), half as much again as the sedan's that the filter took before."""
    config = load_config("circle", overrides=["car=vw-vanagon"], duration_s=12.0)
    result = run(config, tmp_path / "circle.mcap")
    assert result.completed
    truth = [m for _, m in iter_messages(result.log_path, "/vehicle/truth")]
    steady = [m for m in truth if m["t_s"] > 8.0]
    gradient = abs(np.mean([m["roll_rad"] for m in steady])
                   / np.mean([m["ay_mps2"] for m in steady]))
    assert gradient == pytest.approx(_mode_of(config.plant).gradient_radpmps2, rel=0.05)
    assert gradient > 1.3 * EstimatorConfig().roll_gradient_radpmps2
