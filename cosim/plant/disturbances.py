"""Unmeasured disturbances on the plant: the ``disturbances:`` list of a scenario.

The ``dynamic-mpc`` design is tested against an unmeasured step on the heading, held for
one control period ``Ts``, of up to 5 deg. On the MuJoCo car the step is a yaw
rate pulse: the chassis's yaw rate is raised by ``angle / duration_s`` for ``duration_s``
(default that design's ``Ts`` = 0.1 s; :meth:`cosim.plant.car.MujocoPlant.add_yaw_rate`), so the
body turns by about ``angle`` while its velocity does not follow at once: the car is
kicked into a side slip, as by a pothole or a gust, and its tyres react. The controller is
not told (unmeasured); the gyro does see the motion, as on a real car.

Why not rotate the car, velocity and all, in one instant (tried): no sensor sees such a
jump (the gyro reads no rate, GNSS no jump), only the course of later GNSS fixes does, and
the EKF's outlier gate then rejects those fixes for ``gate_release_s``: a 5 deg step on the
straight drove the car 3.5 m off the path with the EKF, 0.58 m with the true state.

Each entry fires once, at the first physics step at or after ``t_s``, with an angle drawn
uniformly from ``[-max_rad, max_rad]`` by the run's ``disturbances`` generator (keyed by
name, so adding one leaves the sensors' noise unchanged), or exactly ``angle_rad`` when
``random`` is false.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cosim.core.config_fields import setting
from cosim.core.exceptions import ConfigError

DISTURBANCE_KINDS: tuple[str, ...] = ("heading_step",)
"""Values ``disturbances[i].kind`` accepts."""


@dataclass(frozen=True)
class DisturbanceConfig:
    """One unmeasured disturbance of the plant at one time."""

    kind: str = setting("heading_step", choices=DISTURBANCE_KINDS, doc="what is disturbed")
    t_s: float = setting(5.0, low=0.0, high=1e6, doc="when it fires [s]")
    max_rad: float = setting(
        math.radians(5.0), low=0.0, high=math.pi, doc="largest heading step (seed: 5 deg)"
    )
    random: bool = setting(True, doc="draw the step in [-max_rad, max_rad]; false: angle_rad")
    angle_rad: float = setting(
        math.radians(5.0), low=-math.pi, high=math.pi, doc="the step when random is false"
    )
    duration_s: float = setting(
        0.1, low=1e-3, high=10.0, doc="how long the yaw rate pulse lasts (seed: one Ts)"
    )

    def __post_init__(self) -> None:
        if not self.random and abs(self.angle_rad) > self.max_rad:
            raise ConfigError(f"angle_rad = {self.angle_rad}: expected |angle_rad| <= "
                              f"max_rad = {self.max_rad}")


@dataclass(frozen=True)
class YawRateChange:
    """A change of the chassis's yaw rate at one physics step (half of a heading step)."""

    step: int
    delta_radps: float
    angle_rad: float
    """The heading step this change belongs to."""


def schedule(
    disturbances: tuple[DisturbanceConfig, ...], physics_dt_s: float, rng: np.random.Generator
) -> tuple[YawRateChange, ...]:
    """Every yaw rate change of a run, drawn once at its start, in firing order.

    A heading step of ``angle`` is two changes: ``+angle / T`` at its start and
    ``-angle / T`` after ``T`` (its duration, rounded to whole physics steps).
    """
    changes = []
    for disturbance in disturbances:
        draw = rng.uniform(-disturbance.max_rad, disturbance.max_rad)
        angle = float(draw) if disturbance.random else disturbance.angle_rad
        start = math.ceil(disturbance.t_s / physics_dt_s - 1e-9)
        steps = max(1, round(disturbance.duration_s / physics_dt_s))
        rate = angle / (steps * physics_dt_s)
        changes.append(YawRateChange(start, rate, angle))
        changes.append(YawRateChange(start + steps, -rate, angle))
    return tuple(sorted(changes, key=lambda c: c.step))
