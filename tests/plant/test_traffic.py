"""Traffic cars: scripted motion checked by hand, their MuJoCo bodies, collisions."""

from __future__ import annotations

import math

import mujoco
import pytest
from scipy.integrate import quad

from cosim.core.exceptions import ConfigError
from cosim.core.initial_state import InitialState
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant
from cosim.plant.traffic import CAR_PREFIX, Traffic, TrafficCar, TrafficCarConfig, traffic_cars


def car(**settings: object) -> TrafficCar:
    (name, config), = traffic_cars({"c": settings})
    traffic = Traffic(((name, config),), InitialState(x_m=10.0, y_m=-2.0, yaw_rad=0.5))
    return TrafficCar(name, config, traffic._lane, 4.8, 1.8)


def along_m(c: TrafficCar, t_s: float) -> float:
    """Distance from the ego's start along its initial heading (yaw 0.5 rad)."""
    pose = c.pose(t_s)
    return (pose.x_m - 10.0) * math.cos(0.5) + (pose.y_m + 2.0) * math.sin(0.5)


def test_constant_speed_covers_speed_times_time() -> None:
    c = car(gap_m=30.0, speed_mps=20.0)
    assert along_m(c, 2.0) == pytest.approx(30.0 + 40.0)
    assert c.pose(2.0).speed_mps == pytest.approx(20.0)
    assert c.pose(2.0).yaw_rad == pytest.approx(0.5)


def test_harmonic_distance_is_the_integral_of_its_speed() -> None:
    c = car(gap_m=0.0, speed_profile="harmonic", speed_mps=5.0, amplitude_mps=2.0,
            period_s=8.0, phase_rad=0.3)
    expected, _ = quad(lambda t: 5.0 + 2.0 * math.sin(2 * math.pi * t / 8.0 + 0.3), 0.0, 13.0)
    assert along_m(c, 13.0) == pytest.approx(expected, rel=1e-9)
    assert c.pose(2.0).speed_mps == pytest.approx(5.0 + 2.0 * math.sin(math.pi / 2 + 0.3))


def test_braking_stops_after_v_squared_over_two_a_and_stays() -> None:
    c = car(gap_m=0.0, speed_profile="braking", speed_mps=20.0, brake_t_s=1.0,
            brake_decel_mps2=5.0)
    stop_m = 20.0 + 20.0**2 / (2 * 5.0)  # 1 s at 20 m/s, then 40 m of braking in 4 s
    assert along_m(c, 3.0) == pytest.approx(20.0 + 20.0 * 2.0 - 0.5 * 5.0 * 4.0)
    assert c.pose(3.0).accel_mps2 == pytest.approx(-5.0)
    assert along_m(c, 5.0) == pytest.approx(stop_m)
    assert along_m(c, 60.0) == pytest.approx(stop_m)
    assert c.pose(60.0).speed_mps == 0.0 and c.pose(60.0).accel_mps2 == 0.0


def test_piecewise_profile_accelerates_then_holds() -> None:
    c = car(gap_m=0.0, speed_profile="piecewise", speed_mps=10.0,
            accel_profile=[{"t_s": 2.0, "accel_mps2": 1.0}, {"t_s": 4.0, "accel_mps2": 0.0}])
    assert c.pose(1.0).speed_mps == pytest.approx(10.0)
    assert c.pose(3.0).speed_mps == pytest.approx(11.0)
    assert c.pose(10.0).speed_mps == pytest.approx(12.0)
    assert along_m(c, 10.0) == pytest.approx(20.0 + 22.0 + 72.0)


def test_a_lane_change_ends_on_its_target_offset_heading_straight() -> None:
    c = car(gap_m=0.0, speed_mps=20.0, lateral_offset_m=3.5, lane_change_t_s=1.0,
            lane_change_s=3.0, lane_change_to_m=0.0)
    assert c.lateral_offset(0.5) == (3.5, 0.0)
    offset, rate = c.lateral_offset(2.5)  # half way: half the offset at the largest rate
    assert offset == pytest.approx(1.75)
    assert rate == pytest.approx(-3.5 * math.pi / (2 * 3.0))
    assert c.pose(2.5).yaw_rad == pytest.approx(0.5 + math.atan2(rate, 20.0))
    assert c.lateral_offset(5.0) == (0.0, 0.0)
    assert c.pose(5.0).yaw_rad == pytest.approx(0.5)


@pytest.mark.parametrize(("section", "message"), [
    ({"Lead": {}}, "traffic.'Lead': expected a car name"),
    ({"lead": {"speed_mpz": 3}}, "unknown key 'traffic.lead.speed_mpz'"),
    ({"lead": {"speed_profile": "harmonic", "speed_mps": 2.0, "amplitude_mps": 3.0}},
     "traffic.lead.amplitude_mps = 3: expected at most speed_mps = 2"),
    ({"lead": {"speed_profile": "bouncing"}}, "traffic.lead.speed_profile = 'bouncing'"),
    ({"lead": {"accel_profile": [{"t_s": 2.0}, {"t_s": 1.0}]}}, "strictly increasing"),
])
def test_bad_cars_are_refused_naming_the_key(section, message) -> None:
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        traffic_cars(section)


def plant_with(cars: dict[str, dict[str, object]], speed_mps: float) -> MujocoPlant:
    traffic = Traffic(traffic_cars(cars), InitialState(speed_mps=speed_mps))
    return MujocoPlant(PlantConfig(), 0.002, InitialState(speed_mps=speed_mps), traffic=traffic)


def test_cars_are_named_mocap_bodies_placed_on_their_script() -> None:
    plant = plant_with({"lead": {"gap_m": 40.0, "speed_mps": 10.0},
                        "side": {"gap_m": 5.0, "lateral_offset_m": 3.5, "speed_mps": 25.0}},
                       speed_mps=15.0)
    model, data = plant.model, plant.data
    for _ in range(500):  # 1 s
        plant.advance()
    for name, x_m, y_m in (("lead", 50.0, 0.0), ("side", 30.0, 3.5)):
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{CAR_PREFIX}{name}/")
        assert model.body_mocapid[body] >= 0
        assert data.mocap_pos[model.body_mocapid[body]][:2] == pytest.approx((x_m, y_m))
    assert plant.traffic.collision(data) == ""
    assert plant.traffic.ego_front_m == pytest.approx(
        PlantConfig().cog_front_m + 0.95, abs=1e-9)  # front axle + the sedan's overhang


def test_driving_into_a_stopped_car_is_a_collision_with_that_car() -> None:
    plant = plant_with({"stopped": {"gap_m": 12.0, "speed_mps": 0.0},
                        "beside": {"gap_m": 12.0, "lateral_offset_m": 3.5, "speed_mps": 0.0}},
                       speed_mps=10.0)
    front_m, rear_m = plant.traffic.ego_front_m, 2.4  # the traffic car's half length
    hit, t_s = "", 0.0
    while not hit and t_s < 2.0:
        plant.advance()
        t_s = plant.state().t_s
        hit = plant.traffic.collision(plant.data)
    assert hit == "stopped"
    # Contact as the bumpers meet: 12 m - 2.15 m - 2.4 m at 10 m/s (the car coasts).
    assert t_s == pytest.approx((12.0 - front_m - rear_m) / 10.0, abs=0.03)


def test_a_car_passing_in_the_next_lane_is_no_collision() -> None:
    plant = plant_with({"passing": {"gap_m": -10.0, "lateral_offset_m": 3.0,
                                    "speed_mps": 30.0}}, speed_mps=10.0)
    for _ in range(1000):  # 2 s: it passes the ego 1.2 m beside it
        plant.advance()
        assert plant.traffic.collision(plant.data) == ""


def test_the_plant_without_traffic_has_no_traffic_bodies() -> None:
    plant = MujocoPlant(PlantConfig(), 0.002, InitialState())
    assert plant.traffic is None
    assert "car_" not in plant.mjcf_xml
    assert 'name="chassis_shell"' in plant.mjcf_xml
    shell = mujoco.mj_name2id(plant.model, mujoco.mjtObj.mjOBJ_GEOM, "chassis_shell")
    assert plant.model.geom_contype[shell] == 0  # the nominal car is unchanged


def test_traffic_car_config_defaults_are_valid() -> None:
    assert TrafficCarConfig().speed_profile == "constant"


def test_the_poses_after_steps_are_each_cars_pose_at_those_times() -> None:
    # The rows the compiled physics step places the cars with, built without a pose each:
    # the position and the yaw's quaternion of pose(t) at every step's time, to the bit,
    # while a car changes lanes (a drift in the yaw) on a harmonic speed.
    initial = InitialState(x_m=10.0, y_m=-2.0, yaw_rad=0.5)
    traffic = Traffic(traffic_cars({
        "weaving": {"gap_m": 20.0, "speed_profile": "harmonic", "speed_mps": 15.0,
                    "amplitude_mps": 3.0, "period_s": 4.0, "lateral_offset_m": 3.5,
                    "lane_change_t_s": 0.2, "lane_change_s": 1.0, "lane_change_to_m": 0.0},
        "ahead": {"gap_m": 60.0, "speed_mps": 10.0}}), initial)
    traffic.cars = tuple(TrafficCar(name, config, traffic._lane, 4.8, 1.8)
                         for name, config in traffic.configs)
    rows = traffic.poses_after_steps(0.1, 0.002, 1000)
    assert rows.shape == (1000, 2, 7)
    t_s = 0.1
    for k in range(1000):
        t_s = t_s + 0.002
        for j, c in enumerate(traffic.cars):
            pose = c.pose(t_s)
            half = 0.5 * pose.yaw_rad
            assert rows[k, j].tolist() == [pose.x_m, pose.y_m, 0.0, math.cos(half), 0.0, 0.0,
                                           math.sin(half)]
    weaving = [c.name for c in traffic.cars].index("weaving")
    assert len({row[weaving, 3] for row in rows}) > 100  # its yaw moved
