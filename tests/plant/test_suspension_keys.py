"""The suspension as keys (plant.suspension): the layout follows them, the anti-roll bars
are tendons of the right stiffness, and they shift the handling as textbooks say."""

from __future__ import annotations

import dataclasses
import math

import pytest

from cosim.core.suspension_params import SuspensionParams
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.sedan_model import WHEEL_SIDES, build_sedan, sedan_layout
from tests.conformance.driving import drive, plant_at, speed_loop

BASE = PlantConfig()


def with_suspension(**changes: float) -> PlantConfig:
    return dataclasses.replace(BASE, suspension=SuspensionParams(**changes))


def test_spring_rate_follows_the_ride_frequency_squared_and_damping_its_ratio() -> None:
    base = sedan_layout(BASE, BASE.suspension)
    stiff = sedan_layout(BASE, SuspensionParams(ride_frequency_front_hz=3.0,
                                                damping_ratio=0.25))
    for index, (_wheel, axle, _side) in enumerate(WHEEL_SIDES):
        ratio = 4.0 if axle > 0 else 1.0  # 3.0 Hz against 1.5 Hz at the front
        assert stiff.spring_stiffness_npm[index] == pytest.approx(
            ratio * base.spring_stiffness_npm[index])
        # c = 2 zeta sqrt(k m): half the ratio, twice the frequency at the front.
        assert stiff.damping_nspm[index] == pytest.approx(
            0.5 * math.sqrt(ratio) * base.damping_nspm[index])


def test_roll_inertia_ratio_moves_the_chassis_roll_inertia_only() -> None:
    base = sedan_layout(BASE, BASE.suspension)
    heavier = sedan_layout(BASE, SuspensionParams(roll_inertia_ratio=0.3))
    ixx, iyy, izz = base.chassis_inertia_kgm2
    assert heavier.chassis_inertia_kgm2 == pytest.approx(
        (ixx + 0.1 * BASE.yaw_inertia_kgm2, iyy, izz))


def test_anti_roll_bars_are_named_tendons_of_stiffness_k_over_track_squared() -> None:
    assert not build_sedan(BASE, 0.002).find_all("tendon")
    root = build_sedan(with_suspension(anti_roll_stiffness_front_nmprad=30000.0), 0.002)
    (bar,) = root.find_all("tendon")
    assert bar.name == "front_anti_roll_bar"
    assert bar.stiffness == pytest.approx(30000.0 / BASE.track_m**2)
    coefficients = {joint.joint: joint.coef for joint in bar.joint}
    assert coefficients == {"front_left_suspension": 1.0, "front_right_suspension": -1.0}


def test_each_bar_uses_its_own_axles_track() -> None:
    """K / t^2 with t the bar's axle's track: the same roll stiffness K per radian of that
    axle's roll (q_left - q_right) / t."""
    config = dataclasses.replace(
        with_suspension(anti_roll_stiffness_front_nmprad=30000.0,
                        anti_roll_stiffness_rear_nmprad=20000.0),
        track_front_m=1.5, track_rear_m=1.7)
    bars = {bar.name: bar.stiffness for bar in build_sedan(config, 0.002).find_all("tendon")}
    assert bars == pytest.approx({"front_anti_roll_bar": 30000.0 / 1.5**2,
                                  "rear_anti_roll_bar": 20000.0 / 1.7**2})


def steady_yaw_rate(config: PlantConfig) -> float:
    """Yaw rate of a steady 20 m/s turn at about 0.45 g (mean over 3-4 s)."""
    steer = 0.05
    states = drive(plant_at(20.0, config), 4.0, speed_loop(config, 20.0, lambda _t: steer))
    window = [s.yaw_rate_radps for s in states if s.t_s > 3.0]
    return sum(window) / len(window)


def test_a_front_bar_adds_understeer_and_a_rear_bar_takes_it_away() -> None:
    """More roll stiffness at an axle moves lateral load transfer there, and the tyres'
    load sensitivity makes that axle lose grip in the turn (Milliken and Milliken, "Race
    Car Vehicle Dynamics", SAE 1995, ch. 18): a front bar lowers the yaw rate of a fixed
    steering angle, a rear bar raises it."""
    bar = 40000.0
    none = steady_yaw_rate(BASE)
    front = steady_yaw_rate(with_suspension(anti_roll_stiffness_front_nmprad=bar))
    rear = steady_yaw_rate(with_suspension(anti_roll_stiffness_rear_nmprad=bar))
    assert front < none < rear, (front, none, rear)
