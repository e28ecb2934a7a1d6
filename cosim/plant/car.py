"""The plant: a MuJoCo multibody sedan stepped with the raw ``mujoco`` bindings.

The model is built once with PyMJCF (:mod:`cosim.plant.sedan_model`) and compiled from its XML
(``mjcf_xml``, the model actually simulated, for the log); every joint, body and actuator
address is looked up by name at construction. Per physics step, :meth:`MujocoPlant.advance`
runs the actuator models and then exactly one MuJoCo step (in C for the default plant,
:mod:`cosim.plant.compiled_steps`, several steps a call with :meth:`MujocoPlant.advance_steps`;
the Python below is its reference, bit for bit, and runs with traffic or slip control):

- steering actuator (:mod:`cosim.plant.steering`): first-order lag
  (``steer_time_constant_s``, exact discretisation) with a rate limit
  (``max_steer_rate_radps``) on the bicycle-model angle, clipped to ``max_steer_rad``; the
  left and right wheels get their Ackermann angles through position servos with velocity
  and acceleration feed-forward, so the servo adds no lag of its own;
- drive: the total torque clipped to ``max_drive_torque_nm`` and to the power limit
  ``max_drive_power_w / omega`` (mean spin of the driven wheels), split equally over the
  driven wheels (an open differential);
- brakes: the total torque, clipped to ``max_brake_torque_nm``, is split front/rear with a
  fixed brake balance (``CarParams.brake_front_share``) and acts on each wheel as a smooth
  Coulomb friction ``-T omega / sqrt(omega^2 + omega_0^2)``. It is passed to MuJoCo as the
  spin joint's damping coefficient ``T / sqrt(omega^2 + omega_0^2)``, recomputed every step,
  so the implicitfast integrator treats it implicitly: no chatter at standstill and no
  stability limit on ``omega_0``;
- aerodynamic drag ``1/2 rho C_d A v^2`` and rolling resistance ``C_rr m g`` (faded in by
  ``tanh(v / 0.1 m/s)``) act on the chassis against its horizontal velocity
  (``xfrc_applied``);
- tyres, by ``PlantConfig.tyre_model``:

  - ``pacejka`` (default): the wheel-ground contacts are frictionless (``condim`` 1) and
    carry only the normal force; MuJoCo does the multibody dynamics, suspension, normal
    loads and collisions. The step is split (``mj_step1``, tyre forces, ``mj_step2``,
    exactly ``mj_step`` for the implicitfast integrator): from each wheel's contact
    point, its slip velocity in the wheel's heading frame and the contact's normal force
    of the previous step, :func:`cosim.plant.tyre_model.patch_step` (Magic Formula with a
    relaxing contact patch) gives the longitudinal and lateral tyre force, applied to
    the wheel body at the contact point (``xfrc_applied``: the force and its moment
    about the wheel centre; :mod:`cosim.plant.tyre_forces`). ``tyre_friction`` is the
    tyres' peak friction;
  - ``contact``: MuJoCo's contact friction is the tyre (``condim`` 3, elliptic cone,
    friction ``tyre_friction``): nearly rigid until it slides, so the car steers
    kinematically (no cornering stiffness); kept for comparison.

With ``traffic`` (:class:`cosim.plant.traffic.Traffic`), the traffic cars' mocap bodies are set
to their scripted poses after each step; their body boxes collide with the ego's.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass

import mujoco
import numpy as np

from cosim.core.built_on_disk import kept_on_disk
from cosim.core.built_once import built_once
from cosim.core.compiled_function import CompiledCacheWarning, compiler, host_processor
from cosim.core.exceptions import PhysicsDivergenceError
from cosim.core.initial_state import InitialState
from cosim.core.records import WHEEL_NAMES, ActuatorCommand, VehicleState
from cosim.core.rotations import euler_zyx, quaternion_zyx
from cosim.core.vehicle_params import PlantConfig
from cosim.plant.compiled_steps import STATE as STEPS
from cosim.plant.compiled_steps import CompiledSteps, StateReader, load_steps_library
from cosim.plant.low_level import resistance_constants, resistance_force_n
from cosim.plant.sedan_model import (
    FRONT_WHEELS,
    driven_wheels,
    models_dir,
    sedan_xml_and_assets,
)
from cosim.plant.slip_control import SlipLimiter
from cosim.plant.steering import SteeringActuator
from cosim.plant.traffic import Traffic
from cosim.plant.tyre_forces import PYTHON_STEP_FALLBACK, MagicFormulaTyres, TyreForces

SETTLE_DURATION_S = 1.5
"""Simulated time the car stands at construction to find its static equilibrium [s]. The
slowest mode, body bounce at 1.5 Hz with damping ratio 0.5, decays by e^-7 in 1.5 s."""

BRAKE_SPIN_SCALE_RADPS = 0.1
"""omega_0 of the smooth brake: below this wheel spin the brake torque fades linearly to
zero (0.1 rad/s is 3 cm/s at the tyre) [rad/s]."""

MIN_POWER_SPIN_RADPS = 1.0
"""Below this mean driven-wheel spin the power limit is evaluated at this spin (it would be
infinite at standstill; the torque limit governs there) [rad/s]."""

MAX_VELOCITY_NORM2 = 1e8
"""Squared norm of qvel above which the state counts as diverged: some joint moves faster
than 10 km/s or 10^4 rad/s, which no car does."""

MAX_POSITION_NORM2 = 1e20
"""Squared norm of qpos above which the state counts as diverged (MuJoCo itself flags
positions beyond 1e10; the wheels' spin angles grow without bound, so no tighter limit)."""


class MujocoPlant:
    """The simulated sedan (see the module docstring for what each step does).

    ``physics_dt_s`` is the MuJoCo time step; ``mjcf_xml`` the model actually simulated.
    ``one_call_tyres``: the four Magic Formula tyres in one CasADi call
    (:mod:`cosim.plant.tyre_patches`, the default) or, false, the plain Python reference.
    The constructor settles the car on its suspension and then calls :meth:`reset`.
    """

    def __init__(self, config: PlantConfig, physics_dt_s: float, initial: InitialState,
                 one_call_tyres: bool = True, traffic: Traffic | None = None,
                 settle_here: bool = False) -> None:
        self.config = config
        self.initial = initial
        self.traffic = traffic
        self.physics_dt_s = float(physics_dt_s)
        xml, assets = sedan_xml_and_assets(config, self.physics_dt_s,
                                           traffic.names if traffic is not None else ())
        self.mjcf_xml: str = xml
        self.mjcf_assets: dict[str, bytes] = assets
        self._model = mujoco.MjModel.from_xml_string(xml, assets)
        self._data = mujoco.MjData(self._model)
        self._lookup_names()
        self._configure_actuators()
        self._tyres: MagicFormulaTyres | None = (
            MagicFormulaTyres(config, self._model, self.physics_dt_s, one_call_tyres)
            if config.tyre_model == "pacejka"
            else None
        )
        if self._tyres is not None:
            self._tyres.bind(self._data)
            if one_call_tyres and self._tyres.compiled is None and compiler() is None:
                warnings.warn(f"no working C compiler (gcc, or $CC): {PYTHON_STEP_FALLBACK}",
                              CompiledCacheWarning, stacklevel=2)
        if traffic is not None:
            traffic.bind(self._model)
        self._steps: CompiledSteps | None = self._compiled_steps()
        """The physics steps in one C call (:mod:`cosim.plant.compiled_steps`); None: the
        Python step (slip control, no C compiler, the plain tyre reference)."""
        self._read_state: StateReader | None = None if self._steps is None else \
            self._steps.state_reader(self._pos_slice.start, self._linvel_slice.start,
                                     self._steer_qpos, self._spin_dof)
        """:meth:`state`'s numbers in C, with the compiled steps (the same to the bit)."""
        # The car at rest depends on its configuration alone: found once per process
        # (static_equilibrium), here when the model also holds traffic cars.
        self.equilibrium: StaticEquilibrium = (
            self._settle() if settle_here or traffic is not None
            else static_equilibrium(config, self.physics_dt_s, one_call_tyres))
        """The static equilibrium the car starts from (:meth:`reset`)."""
        self.reset()

    def _compiled_steps(self) -> CompiledSteps | None:
        tyres = self._tyres
        if tyres is None or tyres.compiled is None or self._slip_limiter is not None:
            return None
        library, function = tyres.compiled
        loaded = load_steps_library(function, tyres.graph, tyres.recipe)
        if loaded is None:
            return None
        cfg, steering = self.config, self._steering
        constants = {
            "dt_s": self.physics_dt_s, **steering.constants(),
            "max_drive_power_w": cfg.max_drive_power_w,
            "min_power_spin_radps": MIN_POWER_SPIN_RADPS,
            "brake_spin_scale2": BRAKE_SPIN_SCALE_RADPS**2,
            **{f"brake_share{i}": share
               for i, (_, share) in enumerate(self._brake_share_by_dof)},
            **resistance_constants(cfg),
            "max_velocity_norm2": MAX_VELOCITY_NORM2,
            "max_position_norm2": MAX_POSITION_NORM2,
            "tyre_friction": cfg.tyre_friction,
        }
        m = self._model
        chassis = self._id(mujoco.mjtObj.mjOBJ_BODY, "chassis")
        padded = (*self._driven_dof, 0, 0, 0, 0)
        acts = (*self._drive_act, 0, 0, 0, 0)
        indices = {
            "servo_left": steering.servos[0], "servo_right": steering.servos[1],
            "n_driven": self._n_driven,
            **{f"driven_dof{i}": padded[i] for i in range(4)},
            **{f"drive_act{i}": acts[i] for i in range(4)},
            **{f"spin_dof{i}": dof for i, (dof, _) in enumerate(self._brake_share_by_dof)},
            "linvel_dof": self._linvel_slice.start, "chassis_body": chassis,
            **{f"wheel_body{i}": body for i, body in enumerate(tyres.wheel_bodies)},
            **{f"tyre_geom{i}": geom for i, geom in enumerate(tyres.tyre_geoms)},
        }
        return CompiledSteps(loaded, function, m, self._data, constants, indices,
                             tyres.buffers(), tyres.road_tyres,
                             () if self.traffic is None else self.traffic.mocap_slots)

    # ----------------------------------------------------------------- construction

    def _id(self, kind: mujoco.mjtObj, name: str) -> int:
        index = mujoco.mj_name2id(self._model, kind, name)
        if index < 0:
            raise ValueError(f"the sedan model has no {kind.name[6:].lower()} named {name!r}")
        return index

    def _lookup_names(self) -> None:
        """Addresses of everything the plant reads or writes, by name, once."""
        m, d = self._model, self._data
        joint, body = mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_BODY
        actuator, geom = mujoco.mjtObj.mjOBJ_ACTUATOR, mujoco.mjtObj.mjOBJ_GEOM
        free = self._id(joint, "chassis_free")
        qadr, vadr = int(m.jnt_qposadr[free]), int(m.jnt_dofadr[free])
        # Free joint layout (MuJoCo): qpos = position (3), quaternion w x y z (4);
        # qvel = linear velocity of the body origin in the world frame (3), angular
        # velocity in the body frame (3).
        self._pos_slice = slice(qadr, qadr + 3)
        self._quat_slice = slice(qadr + 3, qadr + 7)
        self._linvel_slice = slice(vadr, vadr + 3)
        self._angvel_slice = slice(vadr + 3, vadr + 6)
        chassis = self._id(body, "chassis")
        self._chassis_force = d.xfrc_applied[chassis, 0:3]  # view: force at the chassis CoM
        self._linvel_view = d.qvel[self._linvel_slice]
        self._qpos_view = d.qpos
        self._qvel_view = d.qvel

        def qpos_adr(name: str) -> int:
            return int(m.jnt_qposadr[self._id(joint, name)])

        def dof_adr(name: str) -> int:
            return int(m.jnt_dofadr[self._id(joint, name)])

        self._wheel_body = tuple(self._id(body, f"{w}_wheel") for w in WHEEL_NAMES)
        self._suspension_qpos = tuple(qpos_adr(f"{w}_suspension") for w in WHEEL_NAMES)
        self._spin_dof = tuple(dof_adr(f"{w}_spin") for w in WHEEL_NAMES)
        self._steer_qpos = tuple(qpos_adr(f"{w}_steer") for w in FRONT_WHEELS)
        steer_servos = tuple(self._id(actuator, f"{w}_steer_servo") for w in FRONT_WHEELS)
        self._steering = SteeringActuator(self.config, m, self.physics_dt_s, steer_servos)
        self._drive_act = tuple(
            self._id(actuator, f"{w}_drive") for w in driven_wheels(self.config.drive)
        )
        self._driven_dof = tuple(dof_adr(f"{w}_spin") for w in driven_wheels(self.config.drive))
        self._tyre_radius_m = self.config.wheel_radius_m
        self._tyre_geom = {self._id(geom, f"{w}_tyre"): w for w in WHEEL_NAMES}
        self._warnings = d.warning.number  # view of MuJoCo's warning counters

    def _configure_actuators(self) -> None:
        """Constants of the actuator models, from the true config and the compiled model."""
        cfg, m = self.config, self._model
        front_share = cfg.brake_front_share
        self._brake_share_by_dof = tuple(
            (dof, 0.5 * (front_share if wheel in FRONT_WHEELS else 1.0 - front_share))
            for wheel, dof in zip(WHEEL_NAMES, self._spin_dof, strict=True)
        )
        self._dof_damping = m.dof_damping  # view: brake coefficients are written here
        self._n_driven = len(self._drive_act)
        driven = driven_wheels(cfg.drive)
        self._slip_limiter = (
            SlipLimiter(cfg.slip_control, cfg.wheel_radius_m,
                        [wheel in driven for wheel in WHEEL_NAMES])
            if cfg.slip_control.enabled else None)

    def _settle(self) -> StaticEquilibrium:
        """Let the car stand until its suspension is at rest: that equilibrium.

        The springs are preloaded for the static corner loads (sedan_layout), so this only
        takes up the tyre contacts' small penetration; it records the chassis height, roll
        and pitch, each suspension deflection and each wheel's rolling radius (centre to
        the contact point, which MuJoCo places mid-way through the penetration).
        """
        m, d = self._model, self._data
        mujoco.mj_resetData(m, d)
        if self._tyres is not None:
            self._tyres.reset((0.0, 0.0, 0.0, 0.0))
        n_steps = max(1, math.ceil(SETTLE_DURATION_S / self.physics_dt_s))
        if self._steps is not None:  # in one C call: the same steps and checks
            self._steps.state[STEPS["load0_n"]:STEPS["load0_n"] + 4] = 0.0
            if not self._steps.settle(n_steps):
                self._check(d.time)  # raises: the C step's checks failed
                raise PhysicsDivergenceError(f"physics diverged at t = {d.time:.4f} s while "
                                             "the car settled")
        else:
            for _ in range(n_steps):
                self._physics_step()
                self._check(d.time)
        mujoco.mj_forward(m, d)
        self._check(d.time)
        qpos = d.qpos.tolist()
        qw, qx, qy, qz = qpos[self._quat_slice]
        roll, pitch, _ = euler_zyx(qw, qx, qy, qz)
        radius = self._tyre_radius_m
        loads = dict.fromkeys(WHEEL_NAMES, 0.0)
        wrench = np.zeros(6)
        for i in range(d.ncon):
            contact = d.contact[i]
            for geom in (int(contact.geom1), int(contact.geom2)):
                if geom in self._tyre_geom:
                    mujoco.mj_contactForce(m, d, i, wrench)
                    loads[self._tyre_geom[geom]] += float(wrench[0])
        return StaticEquilibrium(
            z_m=qpos[self._pos_slice][2], roll_rad=roll, pitch_rad=pitch,
            suspension_m=tuple(qpos[a] for a in self._suspension_qpos),
            rolling_radius_m=tuple(0.5 * (radius + float(d.xpos[b, 2]))
                                   for b in self._wheel_body),
            static_load_n=tuple(loads[w] for w in WHEEL_NAMES))

    # ------------------------------------------------------------------- protocol

    def reset(self) -> None:
        """Put the car at ``initial``: pose, forward speed, wheels rolling, suspension at rest.

        Roll, pitch, chassis height and suspension deflections are those of the static
        equilibrium found at construction, so the car starts without a bounce; each wheel
        spins at ``v / r_roll``, its rolling radius, so the tyres start without slip (Magic
        Formula tyres: undeflected, carrying their static loads). Actuator states and
        commands are zero (no drive, no brake, steering straight). Traffic cars, if any, are
        back at their start.
        """
        m, d, init, eq = self._model, self._data, self.initial, self.equilibrium
        mujoco.mj_resetData(m, d)
        qpos, qvel = d.qpos, d.qvel
        qpos[self._pos_slice] = (init.x_m, init.y_m, eq.z_m)
        qpos[self._quat_slice] = quaternion_zyx(init.yaw_rad, eq.pitch_rad, eq.roll_rad)
        for adr, value in zip(self._suspension_qpos, eq.suspension_m, strict=True):
            qpos[adr] = value
        speed = init.speed_mps
        qvel[self._linvel_slice] = (
            speed * math.cos(init.yaw_rad),
            speed * math.sin(init.yaw_rad),
            0.0,
        )
        for dof, radius in zip(self._spin_dof, eq.rolling_radius_m, strict=True):
            qvel[dof] = speed / radius
        for dof in self._spin_dof:
            self._dof_damping[dof] = 0.0
        if self._tyres is not None:
            self._tyres.reset(eq.static_load_n)
        mujoco.mj_forward(m, d)
        self._check(d.time)
        self._drive_cmd_nm = 0.0
        self._brake_cmd_nm = 0.0
        if self._slip_limiter is not None:
            self._slip_limiter.reset()
        self._steering.reset()
        self._prev_linvel = self._linvel_view.tolist()
        if self._steps is not None:
            state = self._steps.state
            state[:] = 0.0
            state[[STEPS["prev_vx_mps"], STEPS["prev_vy_mps"], STEPS["prev_vz_mps"]]] = \
                self._prev_linvel
            state[STEPS["load0_n"]:STEPS["load0_n"] + 4] = eq.static_load_n
        self._last_command: ActuatorCommand | None = None
        if self.traffic is not None:
            self.traffic.place(d, 0.0)
            mujoco.mj_forward(m, d)

    def restart(self, initial: InitialState) -> None:
        """:meth:`reset` to a new ``initial`` state: the next run of the same car, without
        building it again (its model, tyres and compiled step are those of ``config``; the
        static equilibrium found at construction does not depend on the initial state)."""
        self.initial = initial
        self.reset()

    def add_yaw_rate(self, delta_radps: float) -> None:
        """Raise the chassis's yaw rate by ``delta_radps`` at once (a yaw disturbance).

        The chassis's angular velocity about its own z axis changes; its linear velocity
        does not, so the body turns away from its course and the tyres react
        (:mod:`cosim.plant.disturbances`).
        """
        self._data.qvel[self._angvel_slice.start + 2] += delta_radps
        mujoco.mj_forward(self._model, self._data)

    def apply(self, actuator: ActuatorCommand) -> None:
        """Set the actuators' targets; they act from the next :meth:`advance` on.

        Torques are clipped to the true limits of the car here and in :meth:`advance` (the
        power limit depends on the wheel speed at each step); the steering angle is clipped
        to ``max_steer_rad`` and passed through the steering actuator's lag and rate limit.
        """
        cfg = self.config
        self._drive_cmd_nm = min(actuator.drive_torque_nm, cfg.max_drive_torque_nm)
        self._brake_cmd_nm = min(actuator.brake_torque_nm, cfg.max_brake_torque_nm)
        self._steering.command_rad = actuator.steer_rad
        self._last_command = actuator
        if self._steps is not None:
            state = self._steps.state
            state[STEPS["command_rad"]] = actuator.steer_rad
            state[STEPS["drive_cmd_nm"]] = self._drive_cmd_nm
            state[STEPS["brake_cmd_nm"]] = self._brake_cmd_nm

    def advance(self) -> None:
        """Run the actuator models and exactly one MuJoCo step of ``physics_dt_s``."""
        self.advance_steps(1)

    def advance_steps(self, n: int) -> None:
        """:meth:`advance` ``n`` times: in one C call (:mod:`cosim.plant.compiled_steps`)
        where the plant has one, the same operations in the same order."""
        steps = self._steps
        if steps is None:
            for _ in range(n):
                self._advance_in_python()
            return
        poses = None if self.traffic is None else \
            self.traffic.poses_after_steps(self._data.time, self.physics_dt_s, n)
        if not steps.advance(n, poses):
            self._check(self._data.time)  # raises: the C step's checks failed
            raise PhysicsDivergenceError(
                f"physics diverged at t = {self._data.time:.4f} s (physics_dt_s = "
                f"{self.physics_dt_s})")
        state = steps.state
        self._prev_linvel = [state[STEPS["prev_vx_mps"]], state[STEPS["prev_vy_mps"]],
                             state[STEPS["prev_vz_mps"]]]

    def _advance_in_python(self) -> None:
        """One step of the actuators and MuJoCo in Python (the reference of the C step)."""
        d, dt = self._data, self.physics_dt_s
        qvel = self._qvel_view.tolist()
        self._steering.step(d.ctrl)
        self._drive_and_brake(d.ctrl, qvel)
        self._resist(qvel)
        self._prev_linvel = qvel[self._linvel_slice]
        t_before = d.time
        self._physics_step()
        self._check(t_before + dt)
        if self.traffic is not None:
            self.traffic.place(d, d.time)

    def _drive_and_brake(self, ctrl: np.ndarray, qvel: list[float]) -> None:
        """Drive: torque and power limit, split equally over the driven wheels (an open
        differential); brakes: smooth Coulomb friction, as an implicit damping coefficient
        per wheel (module docstring)."""
        cfg, dt = self.config, self.physics_dt_s
        drive = self._drive_cmd_nm
        if drive > 0.0:
            spin = sum(abs(qvel[dof]) for dof in self._driven_dof) / self._n_driven
            drive = min(drive, cfg.max_drive_power_w / max(spin, MIN_POWER_SPIN_RADPS))
        brake = self._brake_cmd_nm
        if self._slip_limiter is not None:  # plant.slip_control (cosim.plant.slip_control)
            limited = self._slip_limiter.limit(drive, brake,
                                               [qvel[dof] for dof in self._spin_dof], dt)
            drive, brake = limited.drive_torque_nm, limited.brake_torque_nm
        per_wheel = drive / self._n_driven
        for act in self._drive_act:
            ctrl[act] = per_wheel
        damping = self._dof_damping
        for dof, share in self._brake_share_by_dof:
            omega = qvel[dof]
            damping[dof] = brake * share / math.sqrt(omega * omega + BRAKE_SPIN_SCALE_RADPS**2)

    def _resist(self, qvel: list[float]) -> None:
        """Drag and rolling resistance against the horizontal velocity of the chassis."""
        vx, vy, _ = qvel[self._linvel_slice]
        speed = math.sqrt(vx * vx + vy * vy)  # as the C step has it (not math.hypot's rounding)
        force = self._chassis_force
        if speed > 1e-9:
            scale = resistance_force_n(self.config, speed) / speed
            force[0] = -scale * vx
            force[1] = -scale * vy
        else:
            force[0] = 0.0
            force[1] = 0.0

    def _physics_step(self) -> None:
        """One MuJoCo step; with Magic Formula tyres, their forces are applied mid-step.

        ``mj_step1`` computes the kinematics and contacts of the current state, the tyres
        turn them into forces on the wheels (``xfrc_applied``), ``mj_step2`` integrates,
        and the contacts' normal forces of this step become the tyres' loads for the next.
        The split is exactly ``mj_step`` for the implicitfast integrator.
        """
        m, d = self._model, self._data
        tyres = self._tyres
        if tyres is None:
            mujoco.mj_step(m, d)
            return
        mujoco.mj_step1(m, d)
        tyres.apply_forces(d)
        mujoco.mj_step2(m, d)
        tyres.read_loads(d)

    def state(self) -> VehicleState:
        """The true state at the CoG (see :class:`VehicleState`).

        Read from ``qpos``/``qvel`` (current after the step, unlike MuJoCo's derived
        quantities, which are those of the step's start). Velocities, yaw rate and
        accelerations are in the vehicle frame fixed to the chassis (ISO 8855: x forward,
        y left, z up; it rolls and pitches with the body); the accelerations are the
        kinematic acceleration of the CoG over the last step (no gravity), zero right after
        :meth:`reset`. The CoG is the chassis frame origin, i.e. the car's centre of
        gravity at static equilibrium (suspension travel moves the true one by < 1 mm).
        Read in C where the plant steps in C (:class:`cosim.plant.compiled_steps.StateReader`,
        the same expressions), else by :meth:`state_in_python`.
        """
        reader = self._read_state
        if reader is None:
            return self.state_in_python()
        values = reader(self._prev_linvel, 1.0 / self.physics_dt_s)
        return VehicleState(self._data.time, *values[:12],
                            wheel_speed_radps=tuple(values[12:]))  # type: ignore[arg-type]

    def state_in_python(self) -> VehicleState:
        """:meth:`state` in plain floats (the reference the C is held to)."""
        qpos = self._qpos_view.tolist()
        qvel = self._qvel_view.tolist()
        x, y, z = qpos[self._pos_slice]
        qw, qx, qy, qz = qpos[self._quat_slice]
        roll, pitch, yaw = euler_zyx(qw, qx, qy, qz)
        # First two columns of the body-to-world rotation matrix: the vehicle x and y axes.
        xx, xy, xz = (
            1.0 - 2.0 * (qy * qy + qz * qz),
            2.0 * (qx * qy + qw * qz),
            2.0 * (qx * qz - qw * qy),
        )
        yx, yy, yz = (
            2.0 * (qx * qy - qw * qz),
            1.0 - 2.0 * (qx * qx + qz * qz),
            2.0 * (qy * qz + qw * qx),
        )
        vwx, vwy, vwz = qvel[self._linvel_slice]
        _, _, yaw_rate = qvel[self._angvel_slice]
        pvx, pvy, pvz = self._prev_linvel
        inv_dt = 1.0 / self.physics_dt_s
        awx, awy, awz = (vwx - pvx) * inv_dt, (vwy - pvy) * inv_dt, (vwz - pvz) * inv_dt
        steer_left, steer_right = (qpos[a] for a in self._steer_qpos)
        return VehicleState(
            t_s=self._data.time,
            x_m=x,
            y_m=y,
            z_m=z,
            roll_rad=roll,
            pitch_rad=pitch,
            yaw_rad=yaw,
            vx_mps=xx * vwx + xy * vwy + xz * vwz,
            vy_mps=yx * vwx + yy * vwy + yz * vwz,
            yaw_rate_radps=yaw_rate,
            ax_mps2=xx * awx + xy * awy + xz * awz,
            ay_mps2=yx * awx + yy * awy + yz * awz,
            steer_rad=0.5 * (steer_left + steer_right),
            wheel_speed_radps=tuple(qvel[dof] for dof in self._spin_dof),  # type: ignore[arg-type]
        )

    # ----------------------------------------------------------------- inspection

    @property
    def model(self) -> mujoco.MjModel:
        """The compiled MuJoCo model (for inspection and visualisation; do not edit)."""
        return self._model

    @property
    def data(self) -> mujoco.MjData:
        """The MuJoCo data (for inspection and visualisation; do not edit)."""
        return self._data

    @property
    def last_command(self) -> ActuatorCommand | None:
        """The last :class:`ActuatorCommand` applied since :meth:`reset`, if any."""
        return self._last_command

    @property
    def rolling_radius_m(self) -> tuple[float, float, float, float]:
        """Each wheel's loaded rolling radius at static equilibrium, WHEEL_NAMES order."""
        return self.equilibrium.rolling_radius_m  # type: ignore[return-value]

    def tyre_forces(self) -> tuple[TyreForces, ...] | None:
        """Each tyre's load, slip and forces of the last step, ``WHEEL_NAMES`` order;
        ``None`` with ``tyre_model = contact`` (MuJoCo's contacts are the tyres)."""
        return None if self._tyres is None else self._tyres.forces()

    @property
    def static_wheel_load_n(self) -> tuple[float, float, float, float]:
        """Each tyre's normal contact force at static equilibrium, WHEEL_NAMES order [N]."""
        return self.equilibrium.static_load_n  # type: ignore[return-value]

    # -------------------------------------------------------------------- helpers

    def _check(self, t_s: float) -> None:
        """Raise PhysicsDivergenceError on a MuJoCo warning or a non-finite/absurd state."""
        warnings = self._warnings
        if warnings.any():
            names = [mujoco.mjtWarning(i).name for i in range(len(warnings)) if warnings[i]]
            raise PhysicsDivergenceError(
                f"physics diverged at t = {t_s:.4f} s: MuJoCo warning {', '.join(names)} "
                f"(physics_dt_s = {self.physics_dt_s})"
            )
        qpos, qvel = self._qpos_view, self._qvel_view
        if not (qvel.dot(qvel) < MAX_VELOCITY_NORM2 and qpos.dot(qpos) < MAX_POSITION_NORM2):
            raise PhysicsDivergenceError(
                f"physics diverged at t = {t_s:.4f} s: non-finite or absurd position/velocity "
                f"(|qpos| = {float(np.linalg.norm(qpos)):.3g}, "
                f"|qvel| = {float(np.linalg.norm(qvel)):.3g}; physics_dt_s = "
                f"{self.physics_dt_s})"
            )


@dataclass(frozen=True)
class StaticEquilibrium:
    """The car standing at rest (:meth:`MujocoPlant._settle`): chassis height, roll and
    pitch, each suspension deflection and rolling radius, each wheel's load (WHEEL_NAMES
    order)."""

    z_m: float
    roll_rad: float
    pitch_rad: float
    suspension_m: tuple[float, ...]
    rolling_radius_m: tuple[float, ...]
    static_load_n: tuple[float, ...]


@built_once
def static_equilibrium(config: PlantConfig, physics_dt_s: float,
                       one_call_tyres: bool) -> StaticEquilibrium:
    """The static equilibrium of the car of ``config``, found once per process and kept on
    disk (:mod:`cosim.core.built_on_disk`, named by the arguments, the project's code, the
    models, MuJoCo's and PyMJCF's files and the processor, as the compiled steps' library
    is): a car of its own let stand for :data:`SETTLE_DURATION_S` (750 MuJoCo steps of the
    default 2 ms), some 12 ms of a new process's set-up that every run's plant would
    otherwise repeat. JSON keeps every float exactly (``repr``), so the equilibrium read
    back is the one built, to the bit."""
    arguments = repr((config, physics_dt_s, one_call_tyres, host_processor()))
    kept = kept_on_disk("static_equilibrium", arguments,
                        lambda: dataclasses.asdict(_settled(config, physics_dt_s,
                                                            one_call_tyres)),
                        packages=("mujoco", "dm_control.mjcf"), folders=(models_dir(),),
                        valid=_is_equilibrium)
    return StaticEquilibrium(**{name: tuple(value) if isinstance(value, list) else value
                                for name, value in kept.items()})


def _settled(config: PlantConfig, physics_dt_s: float,
             one_call_tyres: bool) -> StaticEquilibrium:
    """A car of ``config`` let settle (:meth:`MujocoPlant._settle`). Its warnings (no C
    compiler) are the plant's to give, once."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CompiledCacheWarning)
        return MujocoPlant(config, physics_dt_s, InitialState(), one_call_tyres,
                           settle_here=True).equilibrium


def _is_equilibrium(value: object) -> bool:
    """Whether ``value`` has the form of a :class:`StaticEquilibrium` as JSON: its fields,
    three floats and three lists of one float per wheel."""
    names = [field.name for field in dataclasses.fields(StaticEquilibrium)]
    if not (isinstance(value, dict) and sorted(value) == sorted(names)):
        return False
    return all(isinstance(value[name], float) for name in names[:3]) and all(
        isinstance(value[name], list) and len(value[name]) == len(WHEEL_NAMES)
        and all(isinstance(v, float) for v in value[name]) for name in names[3:])
