"""The lead car: placed ahead of the ego car, driven by its speed profile, harmless.

Numbers a reader can check: from 20 m/s, braking at 3 m/s^2 from t = 1 s, the lead car has
covered 20 + (20 - 1.5) = 38.5 m at t = 2 s, at 17 m/s; braking at 5 m/s^2 it stops at
t = 1 + 20 / 5 = 5 s after 20 + 20^2 / 10 = 60 m, and stays there.
"""

from __future__ import annotations

import math

import mujoco
import pytest

from cosim.core.exceptions import ConfigError
from cosim.core.initial_state import InitialState
from cosim.core.records import ActuatorCommand
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant
from cosim.plant.lead_car import LeadCarConfig

DT_S = 0.002


def plant_with(lead_car: LeadCarConfig | None, **initial: float) -> MujocoPlant:
    return MujocoPlant(PlantConfig(), DT_S, InitialState(speed_mps=20.0, **initial),
                       lead_car=lead_car)


def advance(plant: MujocoPlant, duration_s: float) -> None:
    for _ in range(round(duration_s / DT_S)):
        plant.advance()


def test_lead_car_is_placed_ahead_along_the_initial_heading() -> None:
    plant = plant_with(LeadCarConfig(gap_m=30.0, lateral_offset_m=3.5),
                       x_m=10.0, y_m=-5.0, yaw_rad=0.5)
    lead = plant.lead_state()
    # 30 m ahead along yaw 0.5 rad, 3.5 m to the left of that line.
    assert lead.x_m == pytest.approx(10.0 + 30.0 * math.cos(0.5) - 3.5 * math.sin(0.5))
    assert lead.y_m == pytest.approx(-5.0 + 30.0 * math.sin(0.5) + 3.5 * math.cos(0.5))
    assert (lead.t_s, lead.yaw_rad, lead.speed_mps) == (0.0, 0.5, 20.0)
    # The rear bumper is 2.4 m behind the centre (models/lead_car.xml).
    assert math.hypot(lead.x_m - lead.rear_x_m, lead.y_m - lead.rear_y_m) == pytest.approx(2.4)
    # MuJoCo draws it there: the mocap body and its rear-bumper site.
    mujoco.mj_forward(plant.model, plant.data)
    body = plant.data.body("lead_car/")
    assert body.xpos.tolist() == pytest.approx([lead.x_m, lead.y_m, 0.0])
    site = plant.data.site("lead_car/rear_bumper")
    assert site.xpos[:2].tolist() == pytest.approx([lead.rear_x_m, lead.rear_y_m])


def test_lead_car_follows_its_speed_profile_and_stops_without_reversing() -> None:
    plant = plant_with(LeadCarConfig(gap_m=30.0, accel_profile=((1.0, -3.0), (2.0, -5.0))))
    advance(plant, 2.0)
    lead = plant.lead_state()
    assert lead.t_s == pytest.approx(plant.state().t_s)
    assert lead.distance_m == pytest.approx(38.5, abs=1e-9)
    assert lead.speed_mps == pytest.approx(17.0, abs=1e-9)
    assert lead.x_m == pytest.approx(30.0 + 38.5, abs=1e-9)
    # From 17 m/s at -5 m/s^2 it stops 3.4 s later after 17^2 / 10 = 28.9 m more.
    advance(plant, 4.0)
    stopped = plant.lead_state()
    assert stopped.speed_mps == 0.0 and stopped.accel_mps2 == 0.0
    assert stopped.distance_m == pytest.approx(38.5 + 28.9, abs=1e-9)
    mujoco.mj_forward(plant.model, plant.data)
    assert plant.data.body("lead_car/").xpos[0] == pytest.approx(30.0 + 67.4)
    plant.reset()
    assert plant.lead_state().distance_m == 0.0


def test_lead_car_does_not_disturb_the_ego_car() -> None:
    # Same drive with and without a lead car 100 m ahead, and with one parked on top of
    # the ego car (it has no colliding geoms): the ego states are bit-identical.
    def drive(lead_car: LeadCarConfig | None) -> list:
        plant = plant_with(lead_car)
        plant.apply(ActuatorCommand(0.0, 400.0, 0.0, 0.05))
        states = []
        for _ in range(1500):
            plant.advance()
            states.append(plant.state())
        return states

    alone = drive(None)
    assert drive(LeadCarConfig(gap_m=100.0, initial_speed_mps=25.0)) == alone
    assert drive(LeadCarConfig(gap_m=0.0, initial_speed_mps=0.0)) == alone


def test_without_lead_car_the_model_has_none() -> None:
    plant = plant_with(None)
    with pytest.raises(ValueError, match="no lead car"):
        plant.lead_state()
    assert plant.model.nmocap == 0
    assert "lead_car" not in plant.mjcf_xml


@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ({"initial_speed_mps": -1.0}, "initial_speed_mps"),
        ({"gap_m": math.nan}, "gap_m"),
        ({"accel_profile": ((1.0, -3.0), (1.0, 0.0))}, "increasing"),
        ({"accel_profile": ((1.0,),)}, "accel_profile"),
    ],
)
def test_lead_car_config_is_validated(fields: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        LeadCarConfig(**fields)
