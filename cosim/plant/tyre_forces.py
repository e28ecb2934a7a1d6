"""The four Magic Formula tyres of the plant: contact geometry in, wheel forces out.

With ``plant.tyre_model: pacejka`` the wheel-ground contacts carry only the normal force;
between ``mj_step1`` and ``mj_step2`` (:meth:`cosim.plant.car.MujocoPlant.advance`) each
wheel's tyre force comes from its contact point, its slip velocity in the wheel's heading
frame and the contact's normal force of the step before, through
:func:`cosim.plant.tyre_model.patch_step` (Magic Formula with a relaxing contact patch), or
the four at once through the compiled :mod:`cosim.plant.tyre_patches`.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
from typing import NamedTuple

import casadi as ca
import mujoco
import numpy as np

from cosim.core.compiled_function import CompiledFunction, function_by_recipe
from cosim.core.records import WHEEL_NAMES
from cosim.core.tyre_params import TyreParams
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.sedan_model import FRONT_WHEELS
from cosim.plant.tyre_model import PATCH_AT_REST, PatchState, patch_step
from cosim.plant.tyre_patches import (
    CONTACT_SIZE,
    FORCE_FIELDS,
    PATCH_STATE_SIZE,
    TYRE_PATCHES,
    road_tyre_numbers,
    tyre_patches_function,
)

PYTHON_STEP_FALLBACK = "the plant's tyres and physics step run in Python, about 3x slower"
"""What the plant does without its compiled tyres (said in the one warning line)."""


class TyreForces(NamedTuple):
    """One tyre at one step (wheel heading frame at the contact, ISO 8855 axes)."""

    load_n: float
    """Normal load used for the step: the contact's normal force of the step before [N]."""
    forward_speed_mps: float
    """Forward speed of the wheel centre, ``V_cx`` [m/s]."""
    slip_velocity_x_mps: float
    """Velocity of the wheel's material point at the contact, along the heading [m/s]."""
    slip_velocity_y_mps: float
    """The same, to the left of the heading [m/s]."""
    force_x_n: float
    """Longitudinal tyre force on the wheel [N]."""
    force_y_n: float
    """Lateral tyre force on the wheel [N]."""


class MagicFormulaTyres:
    """The four Magic Formula tyres of a plant: contact geometry in, wheel forces out.

    Per step, for each wheel with a ground contact: the heading frame at the contact
    (x = spin axis x contact normal, normalised: the wheel's heading in the road plane; y =
    normal x x), the velocity of the wheel's material point at the contact point and of the
    wheel centre (from MuJoCo's ``cvel``: angular velocity and the linear velocity at the
    chassis subtree's centre of mass), and the normal load (the contact's normal force of
    the previous step) go into :func:`cosim.plant.tyre_model.patch_step`; the resulting force acts
    at the contact point: ``xfrc_applied`` of the wheel body holds the force and its moment
    about the wheel's centre of mass (the wheel centre for the sedan).
    """

    def __init__(self, config: PlantConfig, model: mujoco.MjModel, physics_dt_s: float,
                 one_call: bool = True) -> None:
        body, geom = mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_GEOM
        self._dt_s = physics_dt_s
        self._friction = config.tyre_friction
        front = dataclasses.replace(
            config.tyre,
            cornering_stiffness_max_prad=config.tyre.cornering_stiffness_max_prad
            * config.front_cornering_stiffness_scale,
        )
        rear = dataclasses.replace(
            config.tyre,
            cornering_stiffness_max_prad=config.tyre.cornering_stiffness_max_prad
            * config.rear_cornering_stiffness_scale,
        )
        self._params: tuple[TyreParams, ...] = tuple(
            front if wheel in FRONT_WHEELS else rear for wheel in WHEEL_NAMES
        )
        self._wheel_body = tuple(
            mujoco.mj_name2id(model, body, f"{wheel}_wheel") for wheel in WHEEL_NAMES
        )
        self._wheel_of_geom = {
            mujoco.mj_name2id(model, geom, f"{wheel}_tyre"): index
            for index, wheel in enumerate(WHEEL_NAMES)
        }
        if min(self._wheel_body) < 0 or min(self._wheel_of_geom) < 0:
            raise ValueError("the sedan model lacks a <wheel>_wheel body or <wheel>_tyre geom")
        chassis = mujoco.mj_name2id(model, body, "chassis")
        self._root = int(model.body_rootid[chassis])
        self._n_wheels = len(WHEEL_NAMES)
        self._bodies = np.array(self._wheel_body)
        self._contact_buffer = np.zeros(self._n_wheels * CONTACT_SIZE)
        self._state_buffer = np.zeros(self._n_wheels * PATCH_STATE_SIZE)
        self._wrench_buffer = np.zeros((self._n_wheels, 6))
        self._forces_buffer = np.zeros((self._n_wheels, FORCE_FIELDS))
        self._new_state_buffer = np.zeros(self._n_wheels * PATCH_STATE_SIZE)
        self._road_tyres_buffer = road_tyre_numbers(self._friction, self._params)
        """The road's friction and the tyres' numbers, an input of the compiled tyres (one
        library, every road and tyre)."""
        self._compiled: tuple[ctypes.CDLL, ca.Function] | None = None
        """The four tyres as one compiled C call (:mod:`cosim.plant.tyre_patches`); None:
        the plain reference, :func:`cosim.plant.tyre_model.patch_step` per wheel."""
        self._structure = (float(physics_dt_s), self._wheel_body, self._root, int(model.nbody))
        self.recipe = repr(("tyre patches", *self._structure))
        """What the four-tyre function is built from (its library's recipe: a new process
        finds the library, and takes the function from it, without building its graph:
        :func:`cosim.core.compiled_function.function_by_recipe`)."""
        if one_call:
            self._compiled = function_by_recipe(TYRE_PATCHES, self.graph, self.recipe,
                                                fallback=PYTHON_STEP_FALLBACK)
        self._patches: CompiledFunction | None = None
        self.reset((0.0,) * self._n_wheels)

    def bind(self, d: mujoco.MjData) -> None:
        """Point the compiled tyres at ``d``'s arrays (once per MjData: fixed memory)."""
        if self._compiled is None:
            return
        library, function = self._compiled
        self._patches = CompiledFunction(
            library, function,
            [d.cvel, d.xpos, d.xipos, d.xmat, d.subtree_com, self._contact_buffer,
             self._state_buffer, self._road_tyres_buffer],
            [self._wrench_buffer, self._forces_buffer, self._new_state_buffer])

    def graph(self) -> ca.Function:
        """The four tyres as one CasADi function, its graph built (once per process:
        :func:`cosim.plant.tyre_patches.tyre_patches_function`)."""
        return tyre_patches_function(*self._structure)

    @property
    def compiled(self) -> tuple[ctypes.CDLL, ca.Function] | None:
        """The compiled four-tyre function and its library (None: the plain reference)."""
        return self._compiled

    @property
    def wheel_bodies(self) -> tuple[int, ...]:
        """Each wheel's body, ``WHEEL_NAMES`` order."""
        return self._wheel_body

    @property
    def tyre_geoms(self) -> tuple[int, ...]:
        """Each wheel's tyre geom, ``WHEEL_NAMES`` order."""
        by_wheel = {index: geom for geom, index in self._wheel_of_geom.items()}
        return tuple(by_wheel[index] for index in range(self._n_wheels))

    @property
    def road_tyres(self) -> np.ndarray:
        """The compiled function's ``road_tyres`` input: the road's friction, then each
        wheel's tyre numbers (:func:`cosim.plant.tyre_patches.road_tyre_numbers`)."""
        return self._road_tyres_buffer

    def buffers(self) -> tuple[np.ndarray, ...]:
        """The compiled function's own buffers: contacts, patch state, wrenches, forces and
        new patch state (what :mod:`cosim.plant.compiled_steps` fills and reads in place)."""
        return (self._contact_buffer, self._state_buffer, self._wrench_buffer,
                self._forces_buffer, self._new_state_buffer)

    def reset(self, loads_n: tuple[float, ...]) -> None:
        """Undeflected tyres carrying ``loads_n``; no contact seen yet."""
        self._loads_n = list(loads_n)
        self._patch: list[PatchState] = [PATCH_AT_REST] * self._n_wheels
        self._state_buffer[:] = 0.0
        self._contact_efc: list[tuple[int, int]] = []
        self._last: list[tuple[float, ...]] = [
            (load, 0.0, 0.0, 0.0, 0.0, 0.0) for load in loads_n
        ]
        self._forces_buffer[:] = 0.0
        self._forces_buffer[:, 0] = loads_n

    def _contacts(self, d: mujoco.MjData) -> tuple[list[int], list[float]]:
        """Each wheel's deepest ground contact (-1: none) and the sign that turns that
        contact's normal into the tyre; remembers every tyre contact's constraint row."""
        n_wheels = self._n_wheels
        contact_of_wheel: list[int] = [-1] * n_wheels
        normal_sign_of_wheel = [1.0] * n_wheels
        depth_of_wheel = [math.inf] * n_wheels
        contact_efc: list[tuple[int, int]] = []
        ncon = d.ncon
        if ncon:
            contacts = d.contact
            geoms = contacts.geom.tolist()
            dist = contacts.dist.tolist()
            efc_address = contacts.efc_address.tolist()
            wheel_of_geom = self._wheel_of_geom
            for i in range(ncon):
                geom1, geom2 = geoms[i]
                # The contact normal points from geom1 to geom2: up, into the tyre, when the
                # tyre is geom2 (MuJoCo puts the plane first); flipped otherwise.
                sign = 1.0
                wheel = wheel_of_geom.get(geom2, -1)
                if wheel < 0:
                    sign = -1.0
                    wheel = wheel_of_geom.get(geom1, -1)
                    if wheel < 0:
                        continue
                if efc_address[i] >= 0:  # -1: inside the margin but not (yet) a constraint,
                    contact_efc.append((wheel, efc_address[i]))  # so it carries no force
                if dist[i] < depth_of_wheel[wheel]:
                    depth_of_wheel[wheel] = dist[i]
                    contact_of_wheel[wheel] = i
                    normal_sign_of_wheel[wheel] = sign
        self._contact_efc = contact_efc
        return contact_of_wheel, normal_sign_of_wheel

    def apply_forces(self, d: mujoco.MjData) -> None:
        """Set each wheel's ``xfrc_applied`` from the state after ``mj_step1``."""
        if self._patches is None:
            self._apply_forces_reference(d)
            return
        contact_of_wheel, sign_of_wheel = self._contacts(d)
        values: list[float] = []
        if d.ncon:
            positions = d.contact.pos.tolist()
            frames = d.contact.frame.tolist()
        for index, sign, load in zip(contact_of_wheel, sign_of_wheel, self._loads_n,
                                     strict=True):
            if index < 0:
                values += (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, load)
                continue
            frame = frames[index]
            values += (1.0, *positions[index], sign * frame[0], sign * frame[1],
                       sign * frame[2], load)
        self._contact_buffer[:] = values
        self._patches()
        d.xfrc_applied[self._bodies] = self._wrench_buffer
        self._state_buffer[:] = self._new_state_buffer

    def _apply_forces_reference(self, d: mujoco.MjData) -> None:
        """:meth:`apply_forces` in plain Python, :func:`patch_step` per wheel."""
        n_wheels = self._n_wheels
        contact_of_wheel, normal_sign_of_wheel = self._contacts(d)
        if d.ncon:
            positions = d.contact.pos.tolist()
            frames = d.contact.frame.tolist()
        cvel = d.cvel.tolist()
        xpos = d.xpos.tolist()
        xipos = d.xipos.tolist()
        xmat = d.xmat.tolist()
        cx, cy, cz = d.subtree_com[self._root].tolist()
        xfrc = d.xfrc_applied
        loads = self._loads_n
        patches = self._patch
        last = self._last
        friction, dt = self._friction, self._dt_s
        for wheel in range(n_wheels):
            body = self._wheel_body[wheel]
            index = contact_of_wheel[wheel]
            if index < 0:
                patches[wheel] = PATCH_AT_REST
                xfrc[body] = 0.0
                last[wheel] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
                continue
            px, py, pz = positions[index]
            frame = frames[index]
            sign = normal_sign_of_wheel[wheel]
            nx, ny, nz = sign * frame[0], sign * frame[1], sign * frame[2]
            rot = xmat[body]
            ax, ay, az = rot[1], rot[4], rot[7]  # the wheel's spin axis (body y) in the world
            # Heading in the road plane: spin axis x normal, normalised; lateral: normal x it.
            fx, fy, fz = ay * nz - az * ny, az * nx - ax * nz, ax * ny - ay * nx
            norm = math.sqrt(fx * fx + fy * fy + fz * fz)
            fx, fy, fz = fx / norm, fy / norm, fz / norm
            lx, ly, lz = ny * fz - nz * fy, nz * fx - nx * fz, nx * fy - ny * fx
            wx, wy, wz, vx, vy, vz = cvel[body]
            # Velocity of the wheel's material point at the contact and of the wheel centre:
            # v + w x (p - c), with v the velocity at the subtree CoM c (MuJoCo's cvel).
            rx, ry, rz = px - cx, py - cy, pz - cz
            mx = vx + wy * rz - wz * ry
            my = vy + wz * rx - wx * rz
            mz = vz + wx * ry - wy * rx
            ox, oy, oz = xpos[body]
            rx, ry, rz = ox - cx, oy - cy, oz - cz
            forward_speed = (
                (vx + wy * rz - wz * ry) * fx
                + (vy + wz * rx - wx * rz) * fy
                + (vz + wx * ry - wy * rx) * fz
            )
            slip_x = mx * fx + my * fy + mz * fz
            slip_y = mx * lx + my * ly + mz * lz
            load = loads[wheel]
            result = patch_step(
                self._params[wheel], friction, load, forward_speed, slip_x, slip_y,
                patches[wheel], dt,
            )
            patches[wheel] = result.state
            force_x, force_y = result.force_x_n, result.force_y_n
            gx = force_x * fx + force_y * lx
            gy = force_x * fy + force_y * ly
            gz = force_x * fz + force_y * lz
            # Moment of the force at the contact about the wheel's centre of mass: (p - i) x F.
            ix, iy, iz = xipos[body]
            rx, ry, rz = px - ix, py - iy, pz - iz
            xfrc[body] = (gx, gy, gz, ry * gz - rz * gy, rz * gx - rx * gz, rx * gy - ry * gx)
            last[wheel] = (load, forward_speed, slip_x, slip_y, force_x, force_y)

    def read_loads(self, d: mujoco.MjData) -> None:
        """After ``mj_step2``: each tyre's normal load, the sum of its contacts' normal forces
        (``condim`` 1: one constraint row per contact, the normal force)."""
        loads = [0.0] * self._n_wheels
        if self._contact_efc:
            efc_force = d.efc_force
            for wheel, address in self._contact_efc:
                loads[wheel] += float(efc_force[address])
        self._loads_n = loads

    def forces(self) -> tuple[TyreForces, ...]:
        if self._patches is not None:
            return tuple(TyreForces(*values) for values in self._forces_buffer.tolist())
        return tuple(TyreForces(*values) for values in self._last)
