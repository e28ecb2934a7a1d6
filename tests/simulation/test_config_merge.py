"""``--config`` repeated merges in order, key by key, as ``--set`` does (issue: a second
``--config`` silently replaced the first, so a car file and a belief file gave the default
sedan as the plant)."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from cosim.simulation.scenario_config import ConfigMergeNote, config_sources, load_config

COSIM = str(Path(sys.executable).with_name("cosim"))


@pytest.fixture
def car_and_belief(tmp_path: Path) -> tuple[str, str]:
    car = tmp_path / "car.yaml"
    car.write_text("plant:\n  mass_kg: 2000\n  tyre_friction: 0.8\n")
    belief = tmp_path / "belief.yaml"
    belief.write_text("tracker:\n  model:\n    mass_kg: 1900\nplant:\n  tyre_friction: 0.7\n")
    return str(car), str(belief)


def test_a_plant_file_and_a_belief_file_merge(car_and_belief: tuple[str, str]) -> None:
    car, belief = car_and_belief
    with pytest.warns(ConfigMergeNote, match=r"plant.tyre_friction by .*car.yaml and "
                                             r".*belief.yaml \(.*belief.yaml wins\)"):
        config = load_config("lane-change", [car, belief])
    assert config.plant.mass_kg == 2000.0  # from the first file, kept
    assert config.tracker.model.mass_kg == 1900.0  # from the second
    assert config.plant.tyre_friction == 0.7  # both: the later wins
    assert config_sources([car, belief]) == {"plant.mass_kg": car,
                                             "plant.tyre_friction": belief,
                                             "tracker.model.mass_kg": belief}


def test_one_file_and_files_that_share_no_key_say_nothing(
        car_and_belief: tuple[str, str], tmp_path: Path) -> None:
    car, _ = car_and_belief
    other = tmp_path / "other.yaml"
    other.write_text("tracker:\n  horizon: 25\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConfigMergeNote)
        assert load_config("lane-change", car).plant.mass_kg == 2000.0
        both = load_config("lane-change", [car, str(other)])
    assert both.plant.mass_kg == 2000.0 and both.tracker.horizon == 25


def test_config_show_names_the_file_of_each_key(car_and_belief: tuple[str, str]) -> None:
    car, belief = car_and_belief
    done = subprocess.run([COSIM, "config", "show", "lane-change", "--config", car,
                           "--config", belief], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == f"# set by --config {car}: plant.mass_kg"
    assert lines[1] == f"# set by --config {belief}: plant.tyre_friction, tracker.model.mass_kg"
    assert "  mass_kg: 2000.0" in lines and "    mass_kg: 1900.0" in lines
    notes = [line for line in done.stderr.splitlines() if "--config" in line]
    assert len(notes) == 1 and "belief.yaml wins" in notes[0]
