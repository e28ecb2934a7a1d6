"""Physics conformance of the MuJoCo sedan, with numbers a reader can check by hand.

Nominal car (The MathWorks' lane-keeping MPC example): m = 1575 kg, l_f = 1.2 m, l_r = 1.6 m, L =
2.8 m, R = 0.31 m, four wheels of 1 kg m^2, C_d A = 0.66 m^2, C_rr = 0.012. Effective mass for
longitudinal motion m + 4 I_w / R^2 = 1575 + 4 / 0.0961 = 1616.6 kg.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from cosim.core.exceptions import PhysicsDivergenceError
from cosim.core.initial_state import InitialState
from cosim.core.records import ActuatorCommand, Command, VehicleState
from cosim.core.vehicle_params import PlantConfig, VehicleParams
from cosim.plant.car import MujocoPlant
from cosim.plant.low_level import AccelToTorque
from cosim.plant.sedan_model import ackermann_angles

DT_S = 0.002
CONTROL_STEPS = 25  # 50 ms control period
NOMINAL = PlantConfig()
TYRE_MODELS = ("pacejka", "contact")


def plant_at(speed_mps: float, config: PlantConfig = NOMINAL, **initial: float) -> MujocoPlant:
    return MujocoPlant(config, DT_S, InitialState(speed_mps=speed_mps, **initial))


def run(plant: MujocoPlant, duration_s: float, command=None) -> list[VehicleState]:
    """Advance ``duration_s``; ``command(state)`` gives an ActuatorCommand every 50 ms."""
    states = []
    for k in range(round(duration_s / DT_S)):
        if command is not None and k % CONTROL_STEPS == 0:
            plant.apply(command(plant.state()))
        plant.advance()
        states.append(plant.state())
    return states


def hold_accel(accel_mps2: float, steer_rad: float = 0.0, belief: VehicleParams = NOMINAL):
    low_level = AccelToTorque(belief)

    def command(state: VehicleState) -> ActuatorCommand:
        return low_level.convert(Command(state.t_s, accel_mps2, steer_rad), state.vx_mps)

    return command


@pytest.fixture(scope="module")
def nominal_plant() -> MujocoPlant:
    return plant_at(20.0)


def test_static_load_split_matches_the_cog_position(nominal_plant: MujocoPlant) -> None:
    loads = nominal_plant.static_wheel_load_n
    total = sum(loads)
    assert total == pytest.approx(1575.0 * 9.81, rel=5e-3)
    front_share = (loads[0] + loads[1]) / total
    assert front_share == pytest.approx(1.6 / 2.8, rel=0.03)  # l_r / L = 0.571
    assert loads[0] == pytest.approx(loads[1], rel=1e-9)  # left-right symmetric


def test_static_load_split_of_a_variant() -> None:
    plant = plant_at(0.0, PlantConfig(mass_kg=2000.0, cog_front_m=1.4))
    loads = plant.static_wheel_load_n
    assert sum(loads) == pytest.approx(2000.0 * 9.81, rel=5e-3)
    assert (loads[0] + loads[1]) / sum(loads) == pytest.approx(1.6 / 3.0, rel=0.03)


def test_reset_puts_the_car_at_the_initial_state_without_bounce() -> None:
    plant = plant_at(20.0, x_m=3.0, y_m=-2.0, yaw_rad=1.0)
    start = plant.state()
    assert (start.t_s, start.x_m, start.y_m, start.yaw_rad) == pytest.approx((0, 3, -2, 1))
    assert start.vx_mps == pytest.approx(20.0, rel=1e-6)
    assert start.vy_mps == pytest.approx(0.0, abs=1e-9)
    assert start.z_m == pytest.approx(0.55, abs=5e-3)
    for omega, radius in zip(start.wheel_speed_radps, plant.rolling_radius_m, strict=True):
        assert omega * radius == pytest.approx(20.0, rel=1e-6)
    states = run(plant, 1.0)
    heights = [s.z_m for s in states]
    pitches = [s.pitch_rad for s in states]
    assert max(heights) - min(heights) < 1e-3
    assert max(pitches) - min(pitches) < 1e-3
    # reset() starts over exactly.
    end = states[-1]
    plant.reset()
    assert plant.state() == start
    assert run(plant, 1.0)[-1] == end


def test_body_bounce_is_about_1_5_hz_and_well_damped() -> None:
    # Ride frequencies 1.5 Hz front / 1.65 Hz rear, damping ratio 0.5: damped frequency
    # 1.5 * sqrt(1 - 0.25) = 1.3 Hz to 1.43 Hz (half period 0.35 s to 0.38 s), and each
    # swing is exp(-pi 0.5 / sqrt(0.75)) = 0.16 of the one before.
    plant = plant_at(0.0)
    rest_m = plant.state().z_m
    chassis_vz = plant.model.joint("chassis_free").dofadr[0] + 2
    plant.data.qvel[chassis_vz] = -0.2
    heights = np.array([s.z_m - rest_m for s in run(plant, 2.0)])
    turns = [
        i
        for i in range(1, len(heights) - 1)
        if (heights[i] - heights[i - 1]) * (heights[i + 1] - heights[i]) < 0.0
    ]
    half_period_s = (turns[1] - turns[0]) * DT_S
    assert 0.33 < half_period_s < 0.40
    assert -heights[turns[1]] / heights[turns[0]] == pytest.approx(0.16, abs=0.05)


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
def test_coasting_covers_40_m_minus_the_resistance_loss(tyre_model: str) -> None:
    # Drag 0.5 * 1.225 * 0.66 * 20^2 = 161.7 N, rolling 0.012 * 1575 * 9.81 = 185.4 N:
    # deceleration 347.1 N / 1616.6 kg = 0.215 m/s^2, so 2 s cover
    # 40 - 0.5 * 0.215 * 2^2 = 39.57 m and end at 20 - 0.43 = 19.57 m/s.
    plant = plant_at(20.0, PlantConfig(tyre_model=tyre_model))
    end = run(plant, 2.0)[-1]
    assert end.x_m == pytest.approx(39.57, abs=0.05)
    assert end.vx_mps == pytest.approx(19.57, abs=0.02)


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
@pytest.mark.parametrize("drive", ["rwd", "fwd", "awd"])
def test_straight_driving_stays_straight(drive: str, tyre_model: str) -> None:
    # 5 s at 20 m/s with the speed held by drive torque: no crabbing, wheels roll freely.
    plant = plant_at(20.0, PlantConfig(drive=drive, tyre_model=tyre_model))
    states = run(plant, 5.0, hold_accel(0.0))
    end = states[-1]
    assert end.x_m == pytest.approx(100.0, abs=0.5)
    assert max(abs(s.y_m) for s in states) < 0.02
    assert max(abs(s.yaw_rad) for s in states) < 1e-3
    for omega in end.wheel_speed_radps:
        assert omega * 0.31 / end.vx_mps == pytest.approx(1.0, abs=0.01)


def test_constant_small_steer_gives_the_kinematic_yaw_rate_on_contact_tyres() -> None:
    # MuJoCo's contact tyres hardly slip: at 10 m/s with delta = 0.04 rad the yaw rate is
    # the kinematic r = v delta / L = 10 * 0.04 / 2.8 = 0.143 rad/s.
    plant = plant_at(10.0, PlantConfig(tyre_model="contact"))
    end = run(plant, 3.0, hold_accel(0.0, steer_rad=0.04))[-1]
    kinematic = end.speed_mps * 0.04 / 2.8
    assert end.yaw_rate_radps == pytest.approx(kinematic, rel=0.10)
    assert end.steer_rad == pytest.approx(0.04, abs=2e-3)
    # Lateral acceleration of a steady turn: a_y = v r.
    assert end.ay_mps2 == pytest.approx(end.vx_mps * end.yaw_rate_radps, rel=0.05)


def test_constant_small_steer_understeers_on_magic_formula_tyres() -> None:
    # The default tyres understeer by about 2 deg/g = 0.035 rad/g: the yaw rate is the
    # kinematic one divided by 1 + K v^2 / (g L) = 1 + 0.035 * 100 / 27.5 = 1.13 at 10 m/s
    # (tests/conformance measures K itself).
    plant = plant_at(10.0)
    end = run(plant, 3.0, hold_accel(0.0, steer_rad=0.04))[-1]
    kinematic = end.speed_mps * 0.04 / 2.8
    assert 0.80 * kinematic < end.yaw_rate_radps < 0.95 * kinematic
    assert end.steer_rad == pytest.approx(0.04, abs=2e-3)
    assert end.ay_mps2 == pytest.approx(end.vx_mps * end.yaw_rate_radps, rel=0.05)
    # The tyres carry the car: normal loads sum to its weight, lateral forces (each along
    # its wheel's axis, the front ones steered by ~0.04 rad) to m a_y = 1575 v r.
    tyres = plant.tyre_forces()
    assert tyres is not None
    assert sum(t.load_n for t in tyres) == pytest.approx(1575.0 * 9.81, rel=0.01)
    assert sum(t.force_y_n for t in tyres) == pytest.approx(
        1575.0 * end.vx_mps * end.yaw_rate_radps, rel=0.03
    )
    assert plant_at(10.0, PlantConfig(tyre_model="contact")).tyre_forces() is None


def test_tyre_kinematics_match_mujocos_object_velocity() -> None:
    # The plant's hand-written contact kinematics against MuJoCo's own: after a step,
    # MuJoCo's positions, contacts and velocities are still those the tyres used (mj_step2
    # does not recompute them). Reference: mj_objectVelocity at the wheel's CoM, moved to
    # the contact point, in the heading frame (spin axis x up, up x heading).
    plant = plant_at(12.0)
    run(plant, 1.5, hold_accel(1.0, steer_rad=0.08))
    model, data = plant.model, plant.data
    tyres = plant.tyre_forces()
    assert tyres is not None
    velocity = np.zeros(6)
    for wheel, tyre in zip(("front_left", "front_right", "rear_left", "rear_right"), tyres,
                           strict=True):
        body = model.body(f"{wheel}_wheel").id
        geom = model.geom(f"{wheel}_tyre").id
        contact = next(c for c in data.contact[: data.ncon] if geom in (c.geom1, c.geom2))
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, velocity, 0)
        omega, linear = velocity[:3], velocity[3:]
        at_contact = linear + np.cross(omega, contact.pos - data.xipos[body])
        at_centre = linear + np.cross(omega, data.xpos[body] - data.xipos[body])
        normal = contact.frame[:3]
        heading = np.cross(data.xmat[body].reshape(3, 3)[:, 1], normal)
        heading /= np.linalg.norm(heading)
        lateral = np.cross(normal, heading)
        assert tyre.slip_velocity_x_mps == pytest.approx(at_contact @ heading, abs=1e-9)
        assert tyre.slip_velocity_y_mps == pytest.approx(at_contact @ lateral, abs=1e-9)
        assert tyre.forward_speed_mps == pytest.approx(at_centre @ heading, abs=1e-9)
        # The applied force is the tyre force at the contact, with its moment.
        force = tyre.force_x_n * heading + tyre.force_y_n * lateral
        applied = data.xfrc_applied[body]
        np.testing.assert_allclose(applied[:3], force, atol=1e-9)
        np.testing.assert_allclose(
            applied[3:], np.cross(contact.pos - data.xipos[body], force), atol=1e-9
        )
    assert abs(tyres[0].slip_velocity_y_mps) > 1e-3  # it is cornering: the test has teeth


def test_steering_right_turns_right() -> None:
    end = run(plant_at(10.0), 2.0, hold_accel(0.0, steer_rad=-0.04))[-1]
    assert end.yaw_rate_radps < 0.0 and end.y_m < 0.0 and end.ay_mps2 < 0.0


def test_acceleration_demand_of_2_mps2_adds_4_mps_in_2_s() -> None:
    plant = plant_at(10.0)
    end = run(plant, 2.0, hold_accel(2.0))[-1]
    assert end.vx_mps - 10.0 == pytest.approx(4.0, rel=0.15)
    assert end.ax_mps2 == pytest.approx(2.0, rel=0.15)


def test_braking_demand_of_3_mps2_removes_6_mps_in_2_s() -> None:
    plant = plant_at(15.0)
    end = run(plant, 2.0, hold_accel(-3.0))[-1]
    assert end.vx_mps - 15.0 == pytest.approx(-6.0, rel=0.15)
    assert end.ax_mps2 == pytest.approx(-3.0, rel=0.15)


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
def test_braking_to_standstill_is_smooth_and_stays_still(tyre_model: str) -> None:
    # From 5 m/s at -3 m/s^2 the car stops after about 5 / 3 = 1.7 s and 5^2 / 6 = 4.2 m.
    plant = plant_at(5.0, PlantConfig(tyre_model=tyre_model))
    states = run(plant, 4.0, hold_accel(-3.0))
    stopped = [s for s in states if s.t_s > 2.5]
    assert states[-1].x_m == pytest.approx(4.2, abs=0.3)
    assert max(abs(s.vx_mps) for s in stopped) < 1e-3
    assert max(abs(s.ax_mps2) for s in stopped) < 0.05  # no chatter at standstill
    assert max(max(abs(w) for w in s.wheel_speed_radps) for s in stopped) < 1e-2


def test_heavier_car_than_believed_accelerates_less() -> None:
    # Belief 1575 kg, truth 2000 kg: the same torque gives about 1616.6 / 2041.6 of 2 m/s^2.
    plant = plant_at(10.0, PlantConfig(mass_kg=2000.0))
    end = run(plant, 2.0, hold_accel(2.0, belief=VehicleParams()))[-1]
    assert end.vx_mps - 10.0 == pytest.approx(4.0 * 1616.6 / 2041.6, rel=0.1)


@pytest.mark.parametrize(
    ("tyre_model", "low_g", "high_g"),
    # Contact tyres: Coulomb friction, about mu g. Magic Formula tyres: the locked wheels
    # slide at the tail of the curve, 0.53 mu F_z at k = -1 for mu = 0.3 (0.63 at mu = 1,
    # tests/plant/test_tyre_model.py), so the car decelerates at 0.5-0.7 mu g.
    [("contact", 0.8, 1.15), ("pacejka", 0.5, 0.7)],
)
def test_tyre_friction_limits_braking(tyre_model: str, low_g: float, high_g: float) -> None:
    # Full brake torque on a mu = 0.3 road: the tyres' friction limits the deceleration.
    plant = plant_at(20.0, PlantConfig(tyre_friction=0.3, tyre_model=tyre_model))
    states = run(plant, 1.0, lambda s: ActuatorCommand(s.t_s, 0.0, 8000.0, 0.0))
    decel = 20.0 - states[-1].vx_mps
    assert low_g * 0.3 * 9.81 < decel < high_g * 0.3 * 9.81 + 0.2
    assert max(abs(w) for w in states[-1].wheel_speed_radps) < 1.0  # locked


def test_steering_respects_the_rate_limit() -> None:
    # A 0.3 rad step at 0.8 rad/s takes 0.375 s; half way (0.15 rad) at about 0.19 s.
    plant = plant_at(10.0)
    plant.apply(ActuatorCommand(0.0, 0.0, 0.0, 0.3))
    states = run(plant, 1.0)
    for s in states:
        assert s.steer_rad <= 0.8 * 1.03 * s.t_s + 2e-3
    half = next(s.t_s for s in states if s.steer_rad >= 0.15)
    assert half == pytest.approx(0.15 / 0.8, abs=0.02)
    assert states[-1].steer_rad == pytest.approx(0.3, abs=0.01)


def test_steering_lag_is_first_order() -> None:
    # A step small enough for the rate limit (0.01 rad / 0.05 s = 0.2 rad/s < 0.8 rad/s)
    # reaches 1 - 1/e = 63 % after one time constant.
    plant = plant_at(5.0)
    plant.apply(ActuatorCommand(0.0, 0.0, 0.0, 0.01))
    states = run(plant, 0.3)
    at_tau = next(s for s in states if s.t_s >= NOMINAL.steer_time_constant_s - 1e-9)
    assert at_tau.steer_rad == pytest.approx(0.01 * (1.0 - math.exp(-1.0)), abs=5e-4)
    assert states[-1].steer_rad == pytest.approx(0.01, abs=2e-4)


def test_steering_is_clipped_to_max_steer() -> None:
    plant = plant_at(2.0)
    plant.apply(ActuatorCommand(0.0, 0.0, 0.0, 1.0))
    end = run(plant, 1.5)[-1]
    left, right = ackermann_angles(NOMINAL.max_steer_rad, NOMINAL.wheelbase_m, NOMINAL.track_m)
    assert end.steer_rad == pytest.approx(0.5 * (left + right), abs=0.01)


@pytest.mark.parametrize("tyre_model", TYRE_MODELS)
def test_two_plants_from_one_config_are_bit_identical(tyre_model: str) -> None:
    def drive(plant: MujocoPlant) -> VehicleState:
        run(plant, 1000 * DT_S, hold_accel(1.0, steer_rad=0.05))
        return plant.state()

    config = PlantConfig(tyre_model=tyre_model)
    first, second = drive(plant_at(12.0, config)), drive(plant_at(12.0, config))
    assert first == second
    assert first.t_s == pytest.approx(2.0)


def test_absurd_time_step_raises_instead_of_returning_nan(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo appends its warning to MUJOCO_LOG.TXT here
    with pytest.raises(PhysicsDivergenceError, match=r"physics diverged at t = \d"):
        plant = MujocoPlant(NOMINAL, 0.5, InitialState(speed_mps=12.0))
        for _ in range(100):
            plant.advance()
            plant.state()


def test_non_finite_state_raises_with_mujoco_warning(
        nominal_plant: MujocoPlant, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo appends its warning to MUJOCO_LOG.TXT here
    nominal_plant.reset()
    spin = nominal_plant.model.joint("rear_left_spin").dofadr[0]
    nominal_plant.data.qvel[spin] = float("nan")
    with pytest.raises(PhysicsDivergenceError, match="BADQVEL"):
        nominal_plant.advance()
    nominal_plant.reset()
    nominal_plant.advance()
    assert np.isfinite(nominal_plant.state().x_m)


def test_state_is_at_the_cog_in_the_vehicle_frame() -> None:
    # Heading north-west at 10 m/s, coasting: drag 0.40 * 10^2 = 40 N plus rolling 185 N
    # decelerate 1616.6 kg by 0.14 m/s^2, so after 0.5 s: v = 9.93 m/s, 5 - 0.0175 = 4.98 m
    # along the heading; the world velocity rotates into vx = v, vy = 0.
    plant = plant_at(10.0, yaw_rad=2.5)
    end = run(plant, 0.5)[-1]
    assert end.yaw_rad == pytest.approx(2.5, abs=1e-6)
    assert end.vx_mps == pytest.approx(9.93, abs=0.01)
    assert abs(end.vy_mps) < 1e-6
    assert end.x_m == pytest.approx(math.cos(2.5) * 4.98, abs=0.01)
    assert end.y_m == pytest.approx(math.sin(2.5) * 4.98, abs=0.01)
    assert end.ax_mps2 == pytest.approx(-0.14, abs=0.01)
    assert abs(end.ay_mps2) < 1e-6
