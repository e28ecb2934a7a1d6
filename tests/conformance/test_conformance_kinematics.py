"""Conformance at low speed and in a straight line: geometry, not tyres, decides.

Numbers a reader can check: the Ackermann radius of the rear-axle centre is L / tan(delta)
= 2.8 / tan(delta): 55.95 m, 27.91 m and 13.81 m for delta = 0.05, 0.1 and 0.2 rad. At
5 m/s the lateral acceleration is at most 25 / 13.81 = 1.8 m/s^2, so an understeer
gradient of 2 deg/g widens the circle by only K v^2 / (g L) = 0.035 * 25 / 27.5 = 3 %.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.core.vehicle_params import PlantConfig
from tests.conformance.driving import (
    WHEELBASE_M,
    circle_radius_m,
    drive,
    plant_at,
    rear_axle_xy,
    speed_loop,
)

pytestmark = pytest.mark.conformance

TYRE_MODELS = ("pacejka", "contact")
CIRCLE_SPEED_MPS = 5.0
SETTLE_S = 4.0
"""Time to reach the steady circle (steering lag, speed loop) before measuring [s]."""


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
@pytest.mark.parametrize("steer_rad", [0.05, 0.1, 0.2])
def test_low_speed_circle_is_the_ackermann_circle(tyre_model: str, steer_rad: float) -> None:
    config = PlantConfig(tyre_model=tyre_model)
    states = drive(
        plant_at(CIRCLE_SPEED_MPS, config),
        SETTLE_S + 4.0,
        speed_loop(config, CIRCLE_SPEED_MPS, lambda _t: steer_rad),
    )
    arc = np.array([rear_axle_xy(s) for s in states if s.t_s > SETTLE_S])
    radius_m = circle_radius_m(arc)
    ackermann_m = WHEELBASE_M / math.tan(steer_rad)
    assert radius_m == pytest.approx(ackermann_m, rel=0.05)
    assert states[-1].speed_mps == pytest.approx(CIRCLE_SPEED_MPS, abs=0.05)


@pytest.fixture(scope="module", params=TYRE_MODELS)
def straight_run(request: pytest.FixtureRequest) -> list:
    """10 s at 20 m/s, steering straight, speed held."""
    config = PlantConfig(tyre_model=request.param)
    return drive(plant_at(20.0, config), 10.0, speed_loop(config, 20.0, lambda _t: 0.0))


def test_straight_line_at_20_mps_does_not_drift(straight_run: list) -> None:
    # 10 s at 20 m/s: 200 m, less than 5 cm sideways and 0.2 deg of heading.
    assert straight_run[-1].x_m == pytest.approx(200.0, abs=0.5)
    assert max(abs(s.y_m) for s in straight_run) < 0.05
    assert max(abs(math.degrees(s.yaw_rad)) for s in straight_run) < 0.2
    assert max(abs(s.vy_mps) for s in straight_run) < 0.01


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
def test_car_at_rest_stays_put(tyre_model: str) -> None:
    # 10 s standing, no command: it neither creeps (< 1 cm) nor chatters.
    plant = plant_at(0.0, PlantConfig(tyre_model=tyre_model))
    start = plant.state()
    states = drive(plant, 10.0)
    assert max(math.hypot(s.x_m - start.x_m, s.y_m - start.y_m) for s in states) < 0.01
    assert max(abs(s.yaw_rad - start.yaw_rad) for s in states) < 1e-4
    assert max(abs(s.ax_mps2) + abs(s.ay_mps2) for s in states) < 0.01
    assert states[-1].t_s == pytest.approx(10.0)
