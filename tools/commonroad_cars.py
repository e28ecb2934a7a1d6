"""Write ``cosim/cars/*.yaml``: CommonRoad's three published cars as cosim plants, and
their beliefs identified by ``cosim identify``.

    .venv/bin/python tools/commonroad_cars.py        # needs commonroad-vehicle-models (dev)

Source: M. Althoff, M. Koschi, S. Manzinger, "CommonRoad: Composable benchmarks for motion
planning on roads", IEEE Intelligent Vehicles Symposium 2017, and the documentation
"CommonRoad: Vehicle Models" (2020): parameter set 1 (a Ford Escort), 2 (a BMW 320i) and 3
(a VW Vanagon). Each plant takes the set's mass, yaw inertia, CoG position and height,
track widths, wheel radius and spin inertia, road-wheel angle limit and rate; its Magic
Formula tyre is given the set's cornering stiffness ``C_S mu = -p_ky1`` per unit load at
the static axle loads and its friction ellipse ``p_dx1 / p_dy1``, as
``tests/conformance/test_commonroad_cross_check.py`` maps the BMW. The road (``plant.
tyre_friction``), drag and rolling resistance stay the scenario's: the sets have none, a
car on a road has them. The belief beside each is what ``cosim identify --belief-out``
writes for it: the fitted model and the car's data sheet (:mod:`cosim.plant.data_sheet`).
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import yaml

CARS = {"ford-escort": ("parameters_vehicle1", "Ford Escort"),
        "bmw-320i": ("parameters_vehicle2", "BMW 320i"),
        "vw-vanagon": ("parameters_vehicle3", "VW Vanagon")}
"""cosim's name, CommonRoad's parameter function, the car."""

FOLDER = Path(__file__).resolve().parents[1] / "cosim" / "cars"


def plant_keys(p: object) -> dict[str, object]:
    """The ``plant:`` keys of CommonRoad parameter set ``p`` that differ from the default
    plant (:func:`cosim.plant.commonroad_cars.plant_of`)."""
    from cosim.core.vehicle_params import PlantConfig
    from cosim.plant.commonroad_cars import plant_of

    base, car = PlantConfig(), plant_of(p)
    changed: dict[str, object] = {"tyre": {
        f.name: getattr(car.tyre, f.name) for f in dataclasses.fields(car.tyre)
        if getattr(car.tyre, f.name) != getattr(base.tyre, f.name)}}
    changed.update({f.name: getattr(car, f.name) for f in dataclasses.fields(car)
                    if f.name != "tyre" and getattr(car, f.name) != getattr(base, f.name)})
    return {k: (float(f"{v:.6g}") if isinstance(v, float) else v) for k, v in changed.items()}


def main() -> None:
    import importlib

    for name, (function, car) in CARS.items():
        module = importlib.import_module(f"vehiclemodels.{function}")
        keys = plant_keys(getattr(module, function)())
        keys["tyre"] = {k: float(f"{v:.6g}") for k, v in keys["tyre"].items()}
        plant = FOLDER / f"{name}.yaml"
        plant.write_text(
            f"# {car}: CommonRoad's vehicle parameter set ({function}), as a cosim plant.\n"
            "# Written by tools/commonroad_cars.py (Althoff, Koschi, Manzinger, IEEE IV "
            "2017; 'CommonRoad: Vehicle Models', 2020).\n"
            + yaml.safe_dump({"plant": keys}, sort_keys=False))
        belief = FOLDER / f"{name}-belief.yaml"
        root = FOLDER.parents[1]
        done = subprocess.run(
            [str(Path(sys.executable).with_name("cosim")), "identify", "--config",
             str(plant.relative_to(root)), "--belief-out", str(belief.relative_to(root)),
             "--force"], capture_output=True, text=True, cwd=root)
        if done.returncode != 0:
            raise SystemExit(f"{name}: cosim identify failed: {done.stderr.strip()}")
        print(f"{plant.name}, {belief.name}")


if __name__ == "__main__":
    main()
