"""The body's roll mode of a plant, from the numbers its MJCF is built from.

The chassis (sprung mass ``m_s``, its CoM ``h`` above the ground) stands on four vertical
spring-damper struts at the wheels (:func:`cosim.plant.sedan_model.sedan_layout`), so it
rolls about the ground line under it. A roll ``phi`` compresses the struts by ``+-y_i phi``
(``y_i``: a wheel's lateral position) and turns the anti-roll bars by ``phi``, against which
the sprung weight, displaced sideways by ``h phi``, leans::

    K = sum_i k_i y_i^2 + K_arb,f + K_arb,r - m_s g h,     C = sum_i c_i y_i^2
    I = I_xx,s + m_s h^2                                     (about the ground line)
    G = m_s h / K,   omega = sqrt(K / I),   zeta = C / (2 sqrt(K I))

with ``G`` the steady roll per lateral acceleration (Gillespie, "Fundamentals of Vehicle
Dynamics", SAE 1992, ch. 8, roll gradient), ``omega`` the natural frequency and ``zeta``
the damping ratio: the roll mode (R2) of :mod:`estimation.process_model`, whose defaults
are the sedan's (0.0100 rad/(m/s^2), 1.47 Hz, 0.51). A car's belief takes its own from
its data sheet (``tools/commonroad_cars.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosim.core.physical_constants import GRAVITY_MPS2
from cosim.core.suspension_params import SuspensionParams
from cosim.plant.sedan_model import SedanLayout


@dataclass(frozen=True)
class RollMode:
    """The roll mode's three numbers, as ``estimator.roll_*`` takes them."""

    gradient_radpmps2: float
    frequency_hz: float
    damping_ratio: float


def roll_mode(layout: SedanLayout, suspension: SuspensionParams) -> RollMode:
    """The roll mode of the plant built from ``layout`` and ``suspension`` (its anti-roll
    bars), by the module docstring's equations. Raises ``ValueError`` where the struts
    cannot hold the body up in roll (``K <= 0``)."""
    sprung_kg = layout.chassis_mass_kg
    height_m = layout.cog_height_m + layout.chassis_com_m[2]
    arms = [position[1] ** 2 for position in layout.wheel_pos_m]
    stiffness = (sum(k * a for k, a in zip(layout.spring_stiffness_npm, arms, strict=True))
                 + suspension.anti_roll_stiffness_front_nmprad
                 + suspension.anti_roll_stiffness_rear_nmprad
                 - sprung_kg * GRAVITY_MPS2 * height_m)
    if stiffness <= 0.0:
        raise ValueError(f"the body's roll stiffness less its weight's lean is {stiffness:.1f} "
                         "N m/rad: expected a positive one (stiffer springs or a lower CoG)")
    damping = sum(c * a for c, a in zip(layout.damping_nspm, arms, strict=True))
    inertia = layout.chassis_inertia_kgm2[0] + sprung_kg * height_m**2
    return RollMode(
        gradient_radpmps2=sprung_kg * height_m / stiffness,
        frequency_hz=math.sqrt(stiffness / inertia) / (2.0 * math.pi),
        damping_ratio=damping / (2.0 * math.sqrt(stiffness * inertia)),
    )
