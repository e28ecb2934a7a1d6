"""The sedan's suspension and body inertia as configuration: ``plant.suspension``.

A record of the plant's configuration (the MJCF is built from it in
:func:`cosim.plant.sedan_model.sedan_layout`); the defaults are the values the model was
built with before they became keys, so a default run is unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.config_fields import setting


@dataclass(frozen=True)
class SuspensionParams:
    """Springs, dampers, anti-roll bars and the body's roll and pitch inertia."""

    ride_frequency_front_hz: float = setting(
        1.5,
        low=0.3,
        high=10.0,
        doc="undamped bounce frequency of a front corner, sets the spring rate k = m_s "
        "(2 pi f)^2 from the static sprung load; passenger cars 1-1.5 Hz (Gillespie, "
        "Fundamentals of Vehicle Dynamics, 1992, ch. 5) [Hz]",
    )
    ride_frequency_rear_hz: float = setting(
        1.65,
        low=0.3,
        high=10.0,
        doc="the same at the rear: about 10 % above the front (flat ride, Olley; Milliken & "
        "Milliken, Race Car Vehicle Dynamics, 1995, ch. 16) [Hz]",
    )
    damping_ratio: float = setting(
        0.5,
        low=0.01,
        high=3.0,
        doc="damping ratio of each corner (passenger cars 0.2-0.4, Gillespie ch. 5; 0.5: a "
        "disturbance dies out within about one cycle) [-]",
    )
    anti_roll_stiffness_front_nmprad: float = setting(
        0.0,
        low=0.0,
        high=1e6,
        doc="front anti-roll bar: roll moment per radian of the axle's roll, a MuJoCo tendon "
        "of stiffness K / track^2 on the left-minus-right suspension travel; 0: none "
        "[N m/rad]",
    )
    anti_roll_stiffness_rear_nmprad: float = setting(
        0.0, low=0.0, high=1e6, doc="the same at the rear axle [N m/rad]"
    )
    roll_inertia_ratio: float = setting(
        0.2,
        low=0.05,
        high=1.0,
        doc="the whole car's roll inertia about the CoG / its yaw inertia; passenger cars "
        "about a fifth (NHTSA inertial measurements, Heydinger et al., SAE 1999-01-1336) [-]",
    )
    pitch_inertia_ratio: float = setting(
        0.92,
        low=0.1,
        high=2.0,
        doc="the whole car's pitch inertia about the CoG / its yaw inertia; passenger cars "
        "about nine tenths (same source) [-]",
    )
