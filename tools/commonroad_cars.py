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
car on a road has them. The belief beside each is what ``cosim identify`` finds for it.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

if TYPE_CHECKING:
    from cosim.core.vehicle_params import PlantConfig

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
        _add_data_sheet(belief, keys)
        print(f"{plant.name}, {belief.name}")


def _add_data_sheet(belief: Path, plant: dict[str, object]) -> None:
    """The belief file with the car's own figures that identification does not fit
    (tracks, CoG height, wheel radius, steering limits): a controller knows them from the
    car's data sheet; and the filter's load sensitivity of each axle's cornering stiffness
    and its tyres' relaxation length, from its tyre's data sheet (the Magic Formula's at the
    static wheel loads); and its steering's compliance (:func:`steering_belief`)."""
    from cosim.core.vehicle_params import VehicleParams

    text = belief.read_text()
    header = "".join(line + "\n" for line in text.splitlines()
                     if line.startswith("#") and not line.startswith(DATA_SHEET_LINE))
    data = yaml.safe_load(text)
    model = data["tracker"]["model"]
    shared = {f.name for f in dataclasses.fields(VehicleParams)}
    sheet = {k: v for k, v in plant.items() if k in shared and k not in model}
    model.update(sheet)
    data.setdefault("estimator", {}).update(tyre_beliefs(plant))
    data["estimator"].update(steering_belief(plant))
    data["estimator"].update(roll_belief(plant))
    belief.write_text(header + f"{DATA_SHEET_LINE} {', '.join(sheet)}; from its "
                      "tyre's: the estimator's tyre_load_sensitivity_*, "
                      "tyre_relaxation_length_* and wheel_slip_peak_force_ratio; from its "
                      "steering's: steering_compliance_radpnm; from its suspension's: "
                      "roll_gradient_radpmps2, roll_frequency_hz, roll_damping_ratio.\n"
                      + yaml.safe_dump(data, sort_keys=False))


DATA_SHEET_LINE = "# From the car's data sheet:"
"""How the belief file's line naming the data sheet's figures begins (rewritten each time)."""


def _car(plant: dict[str, object]) -> PlantConfig:
    """The default plant with the car's changed ``plant:`` keys but its tyre's."""
    from cosim.core.vehicle_params import PlantConfig

    return dataclasses.replace(PlantConfig(),
                               **{k: v for k, v in plant.items() if k != "tyre"})


def steering_belief(plant: dict[str, object]) -> dict[str, float]:
    """``estimator.steering_compliance_radpnm`` of the car whose changed ``plant:`` keys are
    ``plant``: one over the gain of its steering servo (its front wheels' stiffness about
    the steering axis, :func:`cosim.plant.sedan_model.sedan_layout`)."""
    from cosim.plant.sedan_model import sedan_layout

    car = _car(plant)
    return {"steering_compliance_radpnm":
            float(f"{1.0 / sedan_layout(car).steer_servo_kp_nmprad:.4g}")}


def roll_belief(plant: dict[str, object]) -> dict[str, float]:
    """``estimator.roll_gradient_radpmps2``, ``roll_frequency_hz`` and ``roll_damping_ratio``
    of the car whose changed ``plant:`` keys are ``plant``: the roll mode of its body on its
    suspension (:func:`cosim.plant.roll_mode.roll_mode`), in place of the sedan's."""
    from cosim.plant.roll_mode import roll_mode
    from cosim.plant.sedan_model import sedan_layout

    car = _car(plant)
    mode = roll_mode(sedan_layout(car, car.suspension), car.suspension)
    return {"roll_gradient_radpmps2": float(f"{mode.gradient_radpmps2:.3g}"),
            "roll_frequency_hz": float(f"{mode.frequency_hz:.3g}"),
            "roll_damping_ratio": float(f"{mode.damping_ratio:.2g}")}


def tyre_beliefs(plant: dict[str, object]) -> dict[str, float]:
    """``estimator.tyre_load_sensitivity_front``, ``_rear`` and
    ``estimator.tyre_relaxation_length_front_m``, ``_rear_m`` of the car whose changed
    ``plant:`` keys are ``plant``: its tyre's cornering-stiffness elasticity in the load, and
    its relaxation length ``K_ya / c_y`` (with the axle's cornering-stiffness scale), at the
    static front and rear wheel loads; and ``estimator.wheel_slip_peak_force_ratio``, its
    longitudinal peak force per load on the plant's road at the static front load."""
    from cosim.plant.tyre_model import (
        cornering_stiffness_load_elasticity,
        peak_forces_n,
        relaxation_lengths_m,
    )

    car = _car(plant)
    tyre = dataclasses.replace(car.tyre, **plant.get("tyre", {}))  # type: ignore[arg-type]
    axles = tuple(zip(("front", "rear"), car.static_wheel_loads_n,
                      (car.front_cornering_stiffness_scale, car.rear_cornering_stiffness_scale),
                      strict=True))
    beliefs = {f"tyre_load_sensitivity_{axle}":
               round(cornering_stiffness_load_elasticity(tyre, load), 2)
               for axle, load, _ in axles}
    beliefs.update({f"tyre_relaxation_length_{axle}_m":
                    round(relaxation_lengths_m(tyre, load)[1] * scale, 3)
                    for axle, load, scale in axles})
    front_load = car.static_wheel_loads_n[0]
    beliefs["wheel_slip_peak_force_ratio"] = round(
        peak_forces_n(tyre, front_load, car.tyre_friction)[0] / front_load, 3)
    return beliefs


if __name__ == "__main__":
    main()
