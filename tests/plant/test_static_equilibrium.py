"""The car's static equilibrium, found once per process and kept on disk
(:func:`cosim.plant.car.static_equilibrium`): a plant that reuses it starts exactly as one
that let itself settle, a new process reads it back to the bit without letting a car
settle, and a car of other numbers settles anew."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

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


def test_a_new_process_reads_the_kept_equilibrium_to_the_bit(tmp_path: Path) -> None:
    """The first process lets a car settle and keeps the result; the next one reads it (no
    car settles: ``MujocoPlant._settle`` is not called) and gets the same numbers, each
    float's ``repr`` identical; a third, told to settle, agrees with both."""
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache"), "MUJOCO_GL": "disable"}
    script = """
import sys
from cosim.core.vehicle_params import PlantConfig
from cosim.plant import car
settles = []
real = car.MujocoPlant._settle
car.MujocoPlant._settle = lambda self: settles.append(1) or real(self)
if sys.argv[1] == "settle":
    found = car._settled(PlantConfig(), 0.002, True)
else:
    found = car.static_equilibrium(PlantConfig(), 0.002, True)
print(len(settles), repr(found))
"""
    outputs = [subprocess.run([sys.executable, "-c", script, mode], env=env, check=True,
                              capture_output=True, text=True).stdout.split(" ", 1)
               for mode in ("keep", "read", "settle")]
    assert [settles for settles, _ in outputs] == ["1", "0", "1"]
    assert outputs[0][1] == outputs[1][1] == outputs[2][1]
