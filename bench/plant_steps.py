"""Physics steps per second of the plant, against the raw MuJoCo floor (measures, prints).

    .venv/bin/python bench/plant_steps.py [--steps 20000] [--repeats 5]

For each tyre model: the median over repeats of (a) raw ``mujoco.mj_step`` on the plant's
own model, (b) ``plant.advance()``, (c) ``plant.advance()`` + ``plant.state()`` as the runner
calls them, all at 20 m/s with a small steering angle. Figures from one invocation are
comparable with each other; quote ratios.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

import mujoco

from cosim.core.initial_state import InitialState
from cosim.core.records import ActuatorCommand
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant


def _rate(function, steps: int) -> float:  # noqa: ANN001 - any zero-argument callable
    start = time.perf_counter()
    for _ in range(steps):
        function()
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    tyre_models = ["default"]
    if any(f.name == "tyre_model" for f in dataclasses.fields(PlantConfig)):
        tyre_models = ["pacejka", "contact"]
    for tyre_model in tyre_models:
        config = PlantConfig() if tyre_model == "default" else PlantConfig(tyre_model=tyre_model)
        rows: dict[str, list[float]] = {"mj_step": [], "advance": [], "advance+state": []}
        for _ in range(args.repeats):
            plant = MujocoPlant(config, 0.002, InitialState(speed_mps=20.0))
            plant.apply(ActuatorCommand(0.0, 300.0, 0.0, 0.02))

            def advance_and_state(plant: MujocoPlant = plant) -> None:
                plant.advance()
                plant.state()

            rows["mj_step"].append(
                _rate(lambda p=plant: mujoco.mj_step(p.model, p.data), args.steps))
            plant.reset()
            plant.apply(ActuatorCommand(0.0, 300.0, 0.0, 0.02))
            rows["advance"].append(_rate(plant.advance, args.steps))
            plant.reset()
            plant.apply(ActuatorCommand(0.0, 300.0, 0.0, 0.02))
            rows["advance+state"].append(_rate(advance_and_state, args.steps))
        floor = statistics.median(rows["mj_step"])
        print(f"tyre_model={tyre_model}: median of {args.repeats} x {args.steps} steps")
        for name, rates in rows.items():
            median = statistics.median(rates)
            print(f"  {name:<14} {median:10.0f} steps/s  {1e6 / median:7.1f} us/step  "
                  f"{median / floor:5.2f} x raw mj_step")


if __name__ == "__main__":
    main()
