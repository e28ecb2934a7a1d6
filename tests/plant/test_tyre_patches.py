"""The four tyres in one CasADi call (:mod:`cosim.plant.tyre_patches`) against the plain
reference (:func:`cosim.plant.tyre_model.patch_step` per wheel, in Python)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cosim.core.compiled_function import CompiledFunction, compile_function
from cosim.core.initial_state import InitialState
from cosim.core.records import ActuatorCommand
from cosim.core.tyre_params import TyreParams
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.car import MujocoPlant
from cosim.plant.tyre_model import MIN_LOAD_N, PatchState, patch_step
from cosim.plant.tyre_patches import CONTACT_SIZE, road_tyre_numbers, tyre_patches_function

DT_S = 0.002
FRICTION = 0.9


def _case(rng: np.random.Generator, kind: str) -> tuple[float, float, float, float,
                                                          PatchState]:
    """Load, forward speed, slip velocities and carcass state of one tyre, by kind."""
    load = {"unloaded": 0.5 * MIN_LOAD_N, "light": 400.0}.get(kind, rng.uniform(2e3, 8e3))
    speed = {"standstill": 0.0, "slow": rng.uniform(-2.0, 2.0)}.get(kind, rng.uniform(5, 30))
    slip_x, slip_y = rng.normal(0.0, 0.5, 2)
    if kind == "no slip":
        slip_x = slip_y = 0.0
    if kind == "sliding":
        slip_x, slip_y = rng.normal(0.0, 8.0, 2)
    state = PatchState(*rng.normal(0.0, [2e-3, 5e-3, 0.05, 0.1]))
    if kind == "no slip":
        state = PatchState(0.0, 0.0, 0.0, 0.0)
    return load, speed, slip_x, slip_y, state


KINDS = ("rolling", "no slip", "sliding", "unloaded", "light", "standstill", "slow")


N_BODIES = 6
WHEEL_BODIES = (2, 3, 4, 5)
ROOT = 1


@pytest.mark.parametrize("compiled", [False, True], ids=["casadi", "compiled"])
@pytest.mark.parametrize("kind", KINDS)
def test_one_call_equals_patch_step_per_wheel(kind: str, compiled: bool) -> None:
    # Each wheel: contact at the origin, normal world z, spin axis world y, so the heading
    # frame is the world frame; centre (and centre of mass) 0.3 m above the contact,
    # where cvel is taken (the subtree CoM). The centre moves at cvel's linear velocity
    # (V_cx); the wheel spins about y so that the contact point slips at (V_sx, V_sy).
    # Every output of every wheel must equal the plain reference's to 1e-9 relative (the
    # same floating-point operations, reordered), evaluated by CasADi and compiled to C.
    rng = np.random.default_rng(KINDS.index(kind))
    # The rear tyre differs: its peak friction falls with load (tyre.peak_friction_
    # load_slope) and differs by direction (tyre.longitudinal_friction_scale and
    # lateral_friction_scale, a friction ellipse), so the sliding cases check those too.
    front, rear = TyreParams(), dataclasses.replace(TyreParams(),
                                                    cornering_stiffness_max_prad=12.0,
                                                    peak_friction_load_slope=-0.2,
                                                    longitudinal_friction_scale=1.2,
                                                    lateral_friction_scale=0.95)
    params = (front, front, rear, rear)
    function = tyre_patches_function(DT_S, WHEEL_BODIES, ROOT, N_BODIES)
    cvel, xpos = np.zeros((N_BODIES, 6)), np.zeros((N_BODIES, 3))
    xipos, xmat = np.zeros((N_BODIES, 3)), np.tile(np.eye(3).ravel(), (N_BODIES, 1))
    subtree_com = np.zeros((N_BODIES, 3))
    subtree_com[ROOT] = (0.0, 0.0, 0.3)
    contacts, states, expected = [], [], []
    for wheel_params, body in zip(params, WHEEL_BODIES, strict=True):
        load, speed, slip_x, slip_y, state = _case(rng, kind)
        omega_y = (speed - slip_x) / 0.3  # contact: v + w x (0, 0, -0.3) = v - 0.3 w_y
        cvel[body] = (0.0, omega_y, 0.0, speed, slip_y, 0.0)
        xpos[body] = xipos[body] = (0.0, 0.0, 0.3)
        contacts += [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, load]
        states += list(state)
        reference = patch_step(wheel_params, FRICTION, load, speed, slip_x, slip_y, state,
                               DT_S)
        fx, fy = reference.force_x_n, reference.force_y_n
        # Force at the contact (0, 0, 0) about the centre of mass (0, 0, 0.3): the arm is
        # (0, 0, -0.3), so the moment arm x F is (0.3 F_y, -0.3 F_x, 0).
        expected.append([fx, fy, 0.0, 0.3 * fy, -0.3 * fx, 0.0,
                         load, speed, slip_x, slip_y, fx, fy, *reference.state])
    inputs = [cvel, xpos, xipos, xmat, subtree_com, np.array(contacts), np.array(states),
              road_tyre_numbers(FRICTION, params)]
    if compiled:
        library = compile_function(function)
        assert library is not None, "gcc must compile the tyres (it is on every machine)"
        outputs = [np.zeros((4, 6)), np.zeros((4, 6)), np.zeros(16)]
        CompiledFunction(library, function, inputs, outputs)()
    else:
        outputs = [np.asarray(o) for o in function(*[i.ravel() for i in inputs])]
    wrench, forces, new_states = (o.reshape(4, -1) for o in outputs)
    actual = np.hstack((wrench, forces, new_states))
    np.testing.assert_allclose(actual, np.array(expected), rtol=1e-9, atol=1e-12)
    if kind == "unloaded":
        assert not np.any(actual[:, [0, 1, 10, 11]])  # no force from an unloaded tyre


def test_a_wheel_without_contact_gets_nothing() -> None:
    function = tyre_patches_function(DT_S, WHEEL_BODIES, ROOT, N_BODIES)
    contacts = np.ones(4 * CONTACT_SIZE)
    contacts[::CONTACT_SIZE] = 0.0  # in_contact of every wheel
    arrays = [np.ones(N_BODIES * width) for width in (6, 3, 3, 9, 3)]
    outputs = function(*arrays, contacts, np.ones(16),
                       road_tyre_numbers(FRICTION, (TyreParams(),) * 4))
    assert not any(np.any(np.asarray(o)) for o in outputs)


def _drive(one_call: bool) -> tuple[list[tuple], list]:
    """2 s of a sine steer with drive and brake at 20 m/s; tyre forces and states."""
    plant = MujocoPlant(PlantConfig(), DT_S, InitialState(speed_mps=20.0),
                        one_call_tyres=one_call)
    forces, states = [], []
    for k in range(1000):
        t_s = k * DT_S
        plant.apply(ActuatorCommand(
            t_s=t_s, drive_torque_nm=300.0 if t_s < 1.0 else 0.0,
            brake_torque_nm=0.0 if t_s < 1.0 else 1500.0,
            steer_rad=0.08 * math.sin(2.0 * math.pi * t_s)))
        plant.advance()
        forces.append(plant.tyre_forces())
        states.append(plant.state())
    return forces, states


@pytest.mark.slow
def test_plant_with_one_call_equals_the_plain_reference() -> None:
    # The same plant driven through a sine steer, drive and braking, once with each tyre
    # path: every tyre force of every step and the final state agree to 1e-6 relative
    # (the paths round differently; the difference stays at round-off, 1e-12 measured).
    fast_forces, fast_states = _drive(True)
    plain_forces, plain_states = _drive(False)
    np.testing.assert_allclose(np.array(fast_forces), np.array(plain_forces),
                               rtol=1e-6, atol=1e-6)
    peak_lateral = np.max(np.abs(np.array(plain_forces)[:, :, 5]))
    assert peak_lateral > 1e3  # the manoeuvre loaded the tyres sideways
    for fast, plain in zip(fast_states[-1:], plain_states[-1:], strict=True):
        assert fast.x_m == pytest.approx(plain.x_m, rel=1e-9)
        assert fast.yaw_rad == pytest.approx(plain.yaw_rad, abs=1e-9)
        assert fast.vy_mps == pytest.approx(plain.vy_mps, abs=1e-9)
