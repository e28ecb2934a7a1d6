"""Plausible sedans, one per seed: held-out cars that no one tuned for.

``vehicle_sample: N`` (a top-level config key; -1, the default, is the nominal sedan of
:mod:`cosim.core.vehicle_params`) draws the N-th car and gives it to the plant (the truth)
and to the controller's model (the belief) alike, as :func:`sampled_sedan` states: a car
the controller was told about, not a mismatch (vary ``plant.*`` on top for that). A key
set explicitly in the scenario, ``--config`` or ``--set`` wins over the draw.

Each parameter is drawn uniformly over a published range for passenger cars:

* mass 1200-2100 kg, wheelbase 2.55-3.00 m, the front axle's share of the weight
  0.52-0.62 (front-engined sedans), centre-of-gravity height 0.48-0.60 m: the spread of
  the passenger cars in NHTSA's inertial-parameter measurements (Heydinger et al.,
  "Measured vehicle inertial parameters - NHTSA's data through November 1998", SAE
  1999-01-1336);
* yaw inertia from the dynamic index ``k^2 / (a b) = I_z / (m a b)`` drawn in 0.85-1.05
  (Milliken and Milliken, "Race Car Vehicle Dynamics", SAE 1995, ch. 5: passenger cars lie
  near 1; the nominal sedan's is 0.95);
* the tyres' cornering stiffness, Pacejka's ``p_Ky1`` (``plant.tyre.
  cornering_stiffness_max_prad``), within +-20 % of the reference passenger-car tyre's
  (Pacejka, "Tire and Vehicle Dynamics", 3rd ed. 2012, Appendix 3): cornering coefficients
  of about 0.17-0.25 per degree at the nominal load, the span of passenger-car radials
  (Gillespie, "Fundamentals of Vehicle Dynamics", SAE 1992, ch. 10);
* peak tyre-road friction 0.85-1.1 (dry asphalt with passenger-car tyres: Wong, "Theory of
  Ground Vehicles", 3rd ed., Wiley 2001, Table 1.3, 0.8-0.9 for older tyres; modern ones
  reach about 1.1, Pacejka 2012, ch. 1).

The belief's axle cornering stiffnesses (``tracker.model.cornering_stiffness_*_npr``, the
linear tyres of the dynamic models) follow from the drawn car: the Magic Formula's
cornering stiffness at each tyre's static load (``K = p_Ky1 F_z0 sin(2 atan(F_z / (p_Ky2
F_z0)))``, Pacejka 2012, 4.E25), times two tyres and the plant's effective-stiffness scale
of each axle, times the ratio ``cosim identify`` finds between that estimate and the fit on
the nominal sedan (:data:`IDENTIFIED_OVER_STATIC`), so a sampled car's belief is as good as
the nominal car's. Its filter is told the car as well: the beliefs its data sheet gives
(:mod:`cosim.plant.data_sheet`: each axle's tyre load sensitivity and relaxation length, the
peak force per load on its road, its body's roll gradient, frequency and damping), not the
nominal sedan's.
"""

from __future__ import annotations

import math
import zlib
from typing import Any

import numpy as np

from cosim.core.tyre_params import TyreParams
from cosim.core.vehicle_params import PlantConfig, VehicleParams
from cosim.plant.data_sheet import data_sheet_belief

GRAVITY_MPS2 = 9.81

RANGES: dict[str, tuple[float, float]] = {
    "mass_kg": (1200.0, 2100.0),
    "wheelbase_m": (2.55, 3.00),
    "front_weight_share": (0.52, 0.62),
    "cog_height_m": (0.48, 0.60),
    "dynamic_index": (0.85, 1.05),
    "cornering_stiffness_scale": (0.8, 1.2),
    "tyre_friction": (0.85, 1.10),
}
"""The range each drawn quantity is uniform over (module docstring for the sources)."""

IDENTIFIED_OVER_STATIC = (0.964, 0.984)
"""Front and rear: ``cosim identify``'s axle cornering stiffnesses of the nominal sedan
(72 550 and 79 580 N/rad) over the static-load estimate of :func:`axle_cornering_stiffness_npr`
(75 290 and 80 860 N/rad): the compliance and load transfer the estimate leaves out."""


def axle_cornering_stiffness_npr(plant: PlantConfig, tyre: TyreParams) -> tuple[float, float]:
    """Front and rear axle cornering stiffness of ``plant`` at static load (both tyres,
    each axle's effective-stiffness scale, :data:`IDENTIFIED_OVER_STATIC`) [N/rad]."""
    loads = plant.static_wheel_loads_n
    scales = (plant.front_cornering_stiffness_scale, plant.rear_cornering_stiffness_scale)
    nominal = tyre.nominal_load_n
    stiffness = []
    for load, scale, identified in zip(loads, scales, IDENTIFIED_OVER_STATIC, strict=True):
        per_tyre = tyre.cornering_stiffness_max_prad * nominal * math.sin(
            2.0 * math.atan(load / (tyre.cornering_stiffness_peak_load_ratio * nominal)))
        stiffness.append(2.0 * per_tyre * scale * identified)
    return stiffness[0], stiffness[1]


def sampled_sedan(index: int) -> dict[str, Any]:
    """The ``index``-th sampled sedan as config overrides ``{"plant": ..., "tracker":
    {"model": ...}, "estimator": ...}`` (module docstring); deterministic."""
    rng = np.random.default_rng([index, zlib.crc32(b"sedan_sampler")])
    draw = {name: float(rng.uniform(low, high)) for name, (low, high) in RANGES.items()}
    wheelbase, mass = draw["wheelbase_m"], draw["mass_kg"]
    cog_front = wheelbase * (1.0 - draw["front_weight_share"])
    cog_rear = wheelbase - cog_front
    car = {
        "mass_kg": round(mass, 1),
        "yaw_inertia_kgm2": round(draw["dynamic_index"] * mass * cog_front * cog_rear, 1),
        "cog_front_m": round(cog_front, 4),
        "cog_rear_m": round(cog_rear, 4),
        "cog_height_m": round(draw["cog_height_m"], 4),
        "tyre_friction": round(draw["tyre_friction"], 4),
    }
    tyre = TyreParams(cornering_stiffness_max_prad=round(
        TyreParams().cornering_stiffness_max_prad * draw["cornering_stiffness_scale"], 4))
    plant = PlantConfig(**car, tyre=tyre)
    front, rear = axle_cornering_stiffness_npr(plant, tyre)
    told = VehicleParams(**car)  # the controller is told the car, its road's friction too
    return {
        "plant": {**car, "tyre": {"cornering_stiffness_max_prad":
                                  tyre.cornering_stiffness_max_prad}},
        "tracker": {"model": {**car, "cornering_stiffness_front_npr": round(front, 0),
                              "cornering_stiffness_rear_npr": round(rear, 0)}},
        "estimator": data_sheet_belief(plant, told, fitted=tuple(car)).estimator,
    }
