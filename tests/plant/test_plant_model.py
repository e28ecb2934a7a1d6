"""The sedan's MJCF model: loads in dm_control, names everything, has the configured car."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from cosim.core.initial_state import InitialState
from cosim.core.records import ActuatorCommand
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant
from cosim.plant.sedan_model import (
    ackermann_angles,
    build_sedan,
    import_mjcf,
    models_dir,
    sedan_layout,
    sedan_xml_and_assets,
    sedan_xml_path,
)

DT_S = 0.002

NAMED_OBJECTS = (
    (mujoco.mjtObj.mjOBJ_BODY, "nbody"),
    (mujoco.mjtObj.mjOBJ_JOINT, "njnt"),
    (mujoco.mjtObj.mjOBJ_GEOM, "ngeom"),
    (mujoco.mjtObj.mjOBJ_SITE, "nsite"),
    (mujoco.mjtObj.mjOBJ_CAMERA, "ncam"),
    (mujoco.mjtObj.mjOBJ_LIGHT, "nlight"),
    (mujoco.mjtObj.mjOBJ_MESH, "nmesh"),
    (mujoco.mjtObj.mjOBJ_TEXTURE, "ntex"),
    (mujoco.mjtObj.mjOBJ_MATERIAL, "nmat"),
    (mujoco.mjtObj.mjOBJ_EQUALITY, "neq"),
    (mujoco.mjtObj.mjOBJ_TENDON, "ntendon"),
    (mujoco.mjtObj.mjOBJ_ACTUATOR, "nu"),
    (mujoco.mjtObj.mjOBJ_SENSOR, "nsensor"),
)


def compile_model(config: PlantConfig) -> mujoco.MjModel:
    xml, assets = sedan_xml_and_assets(config, DT_S)
    return mujoco.MjModel.from_xml_string(xml, assets)


def mass_properties(model: mujoco.MjModel) -> tuple[float, np.ndarray, np.ndarray, mujoco.MjData]:
    """Total mass, CoM and inertia tensor about the CoM of the whole car at qpos0.

    Sums each body's inertia (principal moments rotated to the world frame) and moves it to
    the car's CoM with the parallel-axis theorem, from MuJoCo's compiled body masses.
    """
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    chassis = model.body("chassis").id
    total = float(model.body_subtreemass[chassis])
    com = data.subtree_com[chassis].copy()
    inertia = np.zeros((3, 3))
    for body in range(1, model.nbody):
        rotation = data.ximat[body].reshape(3, 3)
        own = rotation @ np.diag(model.body_inertia[body]) @ rotation.T
        r = data.xipos[body] - com
        inertia += own + model.body_mass[body] * (r @ r * np.eye(3) - np.outer(r, r))
    return total, com, inertia, data


@pytest.fixture(scope="module")
def nominal_model() -> mujoco.MjModel:
    return compile_model(PlantConfig())


@pytest.fixture(scope="module", params=["pacejka", "contact"])
def model_per_tyre_model(request: pytest.FixtureRequest) -> mujoco.MjModel:
    return compile_model(PlantConfig(tyre_model=request.param))


def test_models_dir_holds_the_sedan() -> None:
    assert sedan_xml_path().is_file()
    assert (models_dir() / "README.md").is_file()


def test_dm_control_physics_steps_the_shipped_model() -> None:
    mjcf = import_mjcf()
    root = mjcf.from_path(str(sedan_xml_path()))
    physics = mjcf.Physics.from_mjcf_model(root)
    height_m = physics.named.data.qpos["chassis_free"][2]
    for _ in range(500):
        physics.step()
    # One second standing: the car stays on its wheels within a few millimetres.
    assert physics.data.time == pytest.approx(1.0)
    assert physics.named.data.qpos["chassis_free"][2] == pytest.approx(height_m, abs=5e-3)
    assert abs(physics.named.data.qpos["front_left_steer"]) < 1e-6
    assert np.all(np.isfinite(physics.data.qpos))


def test_dm_control_physics_from_a_variant() -> None:
    mjcf = import_mjcf()
    physics = mjcf.Physics.from_mjcf_model(build_sedan(PlantConfig(drive="awd"), DT_S))
    physics.step()
    assert set(physics.named.data.ctrl.axes.row.names) == {
        "front_left_steer_servo",
        "front_right_steer_servo",
        "front_left_drive",
        "front_right_drive",
        "rear_left_drive",
        "rear_right_drive",
    }


def test_components_have_names(model_per_tyre_model: mujoco.MjModel) -> None:
    # After dm_control's suite_test.test_components_have_names; body 0 is MuJoCo's world.
    assert_all_named(model_per_tyre_model)


def assert_all_named(model: mujoco.MjModel) -> None:
    for kind, size_field in NAMED_OBJECTS:
        first = 1 if kind == mujoco.mjtObj.mjOBJ_BODY else 0
        for index in range(first, getattr(model, size_field)):
            name = mujoco.mj_id2name(model, kind, index)
            assert name, f"unnamed {kind.name} with id {index}"


def test_tyre_contacts_per_tyre_model() -> None:
    # Magic Formula tyres: frictionless wheel contacts that carry only the normal force;
    # contact tyres: MuJoCo's friction with condim 3 and the configured mu.
    for tyre_model, condim in (("pacejka", 1), ("contact", 3)):
        model = compile_model(PlantConfig(tyre_model=tyre_model, tyre_friction=0.7))
        for wheel in ("front_left", "front_right", "rear_left", "rear_right"):
            tyre = model.geom(f"{wheel}_tyre")
            assert tyre.condim[0] == condim and tyre.priority[0] == 1
            assert tyre.friction[0] == pytest.approx(0.7)


def test_expected_names_exist(nominal_model: mujoco.MjModel) -> None:
    for wheel in ("front_left", "front_right", "rear_left", "rear_right"):
        nominal_model.body(f"{wheel}_wheel")
        nominal_model.joint(f"{wheel}_suspension")
        nominal_model.joint(f"{wheel}_spin")
        nominal_model.geom(f"{wheel}_tyre")
    for wheel in ("front_left", "front_right"):
        nominal_model.joint(f"{wheel}_steer")
        nominal_model.actuator(f"{wheel}_steer_servo")
    nominal_model.body("chassis")
    nominal_model.geom("ground")
    nominal_model.site("imu")


def test_shipped_xml_is_the_nominal_build(nominal_model: mujoco.MjModel) -> None:
    """models/sedan.xml as written equals what build_sedan makes of the default config."""
    shipped = mujoco.MjModel.from_xml_path(str(sedan_xml_path()))
    fields = (
        "body_mass",
        "body_inertia",
        "body_ipos",
        "body_pos",
        "jnt_range",
        "jnt_stiffness",
        "qpos_spring",
        "dof_damping",
        "geom_size",
        "geom_friction",
        "geom_condim",
        "geom_priority",
        "geom_pos",
        "actuator_gainprm",
        "actuator_biasprm",
        "actuator_ctrlrange",
    )
    for field in fields:
        np.testing.assert_allclose(
            getattr(shipped, field),
            getattr(nominal_model, field),
            rtol=2e-6,
            atol=1e-9,
            err_msg=field,
        )
    assert shipped.opt.timestep == nominal_model.opt.timestep


@pytest.mark.parametrize(
    "config",
    [PlantConfig(), PlantConfig(mass_kg=2000.0, cog_front_m=1.4, yaw_inertia_kgm2=3500.0),
     PlantConfig(track_front_m=1.52, track_rear_m=1.66)],
    ids=["nominal", "heavy-cog-back", "axle-tracks"],
)
def test_mass_yaw_inertia_and_cog_match_the_config(config: PlantConfig) -> None:
    model = compile_model(config)
    total_kg, com, inertia, data = mass_properties(model)
    assert total_kg == pytest.approx(config.mass_kg, rel=1e-12)
    assert inertia[2, 2] == pytest.approx(config.yaw_inertia_kgm2, rel=1e-9)
    # The chassis frame origin is the CoG, at the configured height, l_f / l_r from axles.
    np.testing.assert_allclose(com, data.xpos[model.body("chassis").id], atol=1e-12)
    assert com[2] == pytest.approx(config.cog_height_m, abs=1e-12)
    front = data.xpos[model.body("front_left_wheel").id]
    rear = data.xpos[model.body("rear_right_wheel").id]
    assert front[0] - com[0] == pytest.approx(config.cog_front_m, abs=1e-12)
    assert com[0] - rear[0] == pytest.approx(config.cog_rear_m, abs=1e-12)
    track_front, track_rear = config.axle_tracks_m
    assert 2.0 * front[1] == pytest.approx(track_front, abs=1e-12)
    assert -2.0 * rear[1] == pytest.approx(track_rear, abs=1e-12)
    assert front[2] == pytest.approx(config.wheel_radius_m, abs=1e-12)
    # Principal axes of the car are the vehicle axes (left-right symmetry).
    assert abs(inertia[0, 1]) < 1e-9 and abs(inertia[1, 2]) < 1e-9


def test_config_values_reach_the_model() -> None:
    config = PlantConfig(
        tyre_friction=0.55,
        wheel_radius_m=0.33,
        wheel_mass_kg=25.0,
        wheel_inertia_kgm2=1.3,
        max_steer_rad=0.4,
        track_m=1.55,
        drive="fwd",
    )
    model = compile_model(config)
    for wheel in ("front_left", "front_right", "rear_left", "rear_right"):
        tyre = model.geom(f"{wheel}_tyre")
        assert tyre.friction[0] == pytest.approx(0.55)
        assert tyre.size[0] == pytest.approx(0.33)
        body = model.body(f"{wheel}_wheel")
        assert body.mass[0] == pytest.approx(25.0)
        assert body.inertia[1] == pytest.approx(1.3)
    inner, _ = ackermann_angles(0.4, config.wheelbase_m, 1.55)
    np.testing.assert_allclose(model.joint("front_left_steer").range, [-inner, inner])
    names = {model.actuator(i).name for i in range(model.nu)}
    assert names == {
        "front_left_steer_servo",
        "front_right_steer_servo",
        "front_left_drive",
        "front_right_drive",
    }
    assert model.opt.timestep == DT_S


def test_front_track_and_a_steering_limit_above_one_radian_reach_the_model() -> None:
    """CommonRoad's BMW 320i tracks (front 1.387 m, rear 1.364 m) and road-wheel limit
    (1.066 rad) on the default sedan (wheelbase 2.8 m): the steer joints' range is the
    inner wheel's Ackermann angle at the limit on the front track, atan2(2.8 tan 1.066, 2.8 -
    0.693 tan 1.066) = 1.2749 rad; the servo steers both wheels by the front track's
    Ackermann angles."""
    config = PlantConfig(track_front_m=1.38684, track_rear_m=1.36398, max_steer_rad=1.066)
    model = compile_model(config)
    inner, _ = ackermann_angles(1.066, config.wheelbase_m, 1.38684)
    assert inner == pytest.approx(1.2749, abs=1e-4)
    np.testing.assert_allclose(model.joint("front_left_steer").range, [-inner, inner])
    plant = MujocoPlant(config, DT_S, InitialState(speed_mps=2.0))
    plant.apply(ActuatorCommand(0.0, 0.0, 0.0, 0.3))
    for _ in range(1000):
        plant.advance()
    data = plant.data
    left = data.qpos[model.jnt_qposadr[model.joint("front_left_steer").id]]
    right = data.qpos[model.jnt_qposadr[model.joint("front_right_steer").id]]
    expected = ackermann_angles(0.3, config.wheelbase_m, 1.38684)
    assert (left, right) == pytest.approx(expected, abs=1e-3)
    assert (left, right) != pytest.approx(  # not the geometry of track_m (1.6 m)
        ackermann_angles(0.3, config.wheelbase_m, config.track_m), abs=1e-3)


def test_ackermann_inner_wheel_steers_more() -> None:
    left, right = ackermann_angles(0.1, 2.8, 1.6)
    assert left > 0.1 > right > 0.0
    # Both wheels point at one turn centre on the rear-axle line, R = L / tan(delta).
    radius = 2.8 / np.tan(0.1)
    assert 2.8 / np.tan(left) == pytest.approx(radius - 0.8)
    assert 2.8 / np.tan(right) == pytest.approx(radius + 0.8)
    assert ackermann_angles(-0.1, 2.8, 1.6) == pytest.approx((-right, -left))
    assert ackermann_angles(0.0, 2.8, 1.6) == (0.0, 0.0)


def test_impossible_inertia_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="yaw_inertia_kgm2 = 10.0"):
        sedan_layout(PlantConfig(yaw_inertia_kgm2=10.0))


@pytest.mark.parametrize("physics_dt_s", [0.0, -0.002, float("nan")])
def test_bad_time_step_is_a_config_error(physics_dt_s: float) -> None:
    with pytest.raises(ConfigError, match="physics_dt_s"):
        build_sedan(PlantConfig(), physics_dt_s)
