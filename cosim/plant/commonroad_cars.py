"""CommonRoad's published vehicle parameter sets as cosim plants.

M. Althoff, M. Koschi, S. Manzinger, "CommonRoad: Composable benchmarks for motion planning
on roads", IEEE Intelligent Vehicles Symposium 2017, and the documentation "CommonRoad:
Vehicle Models" (2020) give three cars: parameter set 1 (a Ford Escort), 2 (a BMW 320i), 3
(a VW Vanagon). :func:`plant_of` maps one onto :class:`~cosim.core.vehicle_params.PlantConfig`:
the set's mass, yaw inertia, CoG position and height, track widths, wheel radius and spin
inertia, road-wheel angle limit and rate; the Magic Formula tyre is given the set's
cornering stiffness ``C_S mu = -p_ky1`` per unit load at the static axle loads (nominal
load the static front wheel load, ``p_Ky2 = 9``: the stiffness nearly linear in the load,
as the single-track model's; the rear axle's scale for the same at the rear) and its
friction ellipse ``p_dx1 / p_dy1``. The road (``tyre_friction``), drag and rolling
resistance stay the caller's: the sets have none. ``tools/commonroad_cars.py`` writes
``cosim/cars/`` from it; the conformance cross-check builds its BMW with it.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from cosim.core.vehicle_params import PlantConfig

G_MPS2 = 9.81
PEAK_LOAD_RATIO = 9.0
"""``p_Ky2`` of the mapped tyre."""


def plant_of(p: Any, base: PlantConfig | None = None) -> PlantConfig:
    """``base`` (the default plant) with CommonRoad parameter set ``p`` (an object with
    CommonRoad's attribute names: ``m``, ``I_z``, ``a``, ``b``, ``tire.p_ky1`` ...)."""
    base = base if base is not None else PlantConfig()
    wheelbase = p.a + p.b
    per_load_prad = -p.tire.p_ky1
    front_load = p.m * G_MPS2 * p.b / wheelbase / 2.0
    rear_load = p.m * G_MPS2 * p.a / wheelbase / 2.0

    def shape(load_n: float) -> float:  # K_y / (p_Ky1 F_z0) of the plant's tyre
        return math.sin(2.0 * math.atan(load_n / (PEAK_LOAD_RATIO * front_load)))

    p_ky1 = per_load_prad / shape(front_load)
    rear_scale = per_load_prad * rear_load / (p_ky1 * front_load * shape(rear_load))
    tyre = dataclasses.replace(base.tyre, nominal_load_n=front_load,
                               cornering_stiffness_max_prad=p_ky1,
                               cornering_stiffness_peak_load_ratio=PEAK_LOAD_RATIO,
                               longitudinal_friction_scale=p.tire.p_dx1 / p.tire.p_dy1)
    return dataclasses.replace(
        base, mass_kg=p.m, yaw_inertia_kgm2=p.I_z, cog_front_m=p.a, cog_rear_m=p.b,
        cog_height_m=p.h_cg, track_front_m=p.T_f, track_rear_m=p.T_r, wheel_radius_m=p.R_w,
        wheel_inertia_kgm2=p.I_y_w, max_steer_rad=p.steering.max,
        max_steer_rate_radps=p.steering.v_max, tyre=tyre,
        front_cornering_stiffness_scale=1.0, rear_cornering_stiffness_scale=rear_scale)
