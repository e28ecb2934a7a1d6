"""The filters' dynamic bicycle: its numbers and the axles' lateral forces, built
symbolically with CasADi (the rest of the process model: :mod:`estimation.process_model`).

The slip angles (D1)-(D2) of the axles, at the roll axis's lateral velocity ``vy_a = vy + h p``
(R1), and the tyre laws::

    alpha_f = delta - (vy_a + l_f r) / v_s, alpha_r = -(vy_a - l_r r) / v_s      (D1, D2)
    F_yf = C_f alpha_f,                     F_yr = C_r alpha_r                   (D3)
    F_yi = mu F_zi tanh(C_i alpha_i / (mu F_zi)),  i = f, r                      (D3')

``C_f``, ``C_r`` are the axle cornering stiffnesses of the *belief* (``VehicleParams``) at
the static axle loads ``F_z0i``. Accelerating moves load to the rear axle, braking to the
front, and a tyre's cornering stiffness grows with its load (Pacejka, "Tyre and Vehicle
Dynamics", 3rd ed. 2012, eq. 4.E25, ``K_ya = p_Ky1 F_z0 sin(2 atan(F_z / (p_Ky2 F_z0)))``)::

    F_zf = F_z0f - m a_x h / L,   F_zr = F_z0r + m a_x h / L
    C_i = C_i0 (F_zi / F_z0i)^eps_i                                               (D3'')

with ``eps_i`` each axle's load sensitivity (``estimator.tyre_load_sensitivity_front``,
``_rear``: the elasticity of ``K_ya`` in ``F_z``, ``(1 - u^2) / (1 + u^2)`` with
``u = F_z / (p_Ky2 F_z0)``, 0.58 and 0.74 for the sedan's MF 6.1 tyres at its static wheel
loads, :func:`cosim.plant.tyre_model.cornering_stiffness_load_elasticity`). Left out, the
axles' balance shifts with ``a_x a_y``: on the circuit, accelerating out of a 5 m/s^2 turn
at 1 m/s^2, the model's yaw acceleration was 0.1 rad/s^2 off (``-0.02 a_x a_y``), a side
slip 0.1 m/s off and, the course pinned by the receiver, a heading 10 mrad off that the
filter was sure of. The
``saturating`` tyre law (D3'), the default, is (D3) with a smooth limit at the friction force
``mu F_z`` of the axle load (of (D3'')) (``mu``: the belief's ``tyre_friction``); it has the same
cornering stiffness and differs from (D3) only where the tyres saturate: on the Pacejka
sedan in a 0.8 g lane change the linear law's lateral acceleration is off by 1.7 m/s^2 RMS
where ``|a_y| > 4 m/s^2``, (D3') by 0.24 m/s^2.

In a turn the roll moment ``m h a_y`` moves load from the inner wheels to the outer ones, and
the outer tyres carry more of their axle's force. The front pair is steered, so their forces
then point unequally along the car: a yaw moment against the turn that the bicycle's axles do
not have (the front wheels at ``+-t_f / 2`` across the car)::

    dF_zf = m h a_y (l_r / L) / t_f,   a_y = r vx within +-mu g
    F_yfl - F_yfr = F_w(alpha_f, F_zf / 2 - dF_zf) - F_w(alpha_f, F_zf / 2 + dF_zf)   (D3'''')
    M_z = l_f F_yf - l_r F_yr + t_f / 2 sin(delta) (F_yfl - F_yfr)                     (D5')

with ``F_w`` the front axle's law (D3')-(D3'') for one wheel (half the stiffness, at the
wheel's load), the load moment shared by the axles as their static loads (as the wheel-speed
model shares it, :mod:`estimation.wheel_slip` (S4)) and ``a_y`` the steady turn's, held
within the grip. The axles' own forces stay their laws at the axle loads: along the sedan's
true motion on the circuit (``estimator.lateral_load_transfer``: false leaves (D5') the
axles' moment alone), the bicycle's yaw acceleration without (D5') was 0.0042 rad/s^2 per
m/s^2 of ``a_y`` faster than the car's, 0.02 rad/s^2 in the circuit's 4-6 m/s^2 turns (of
the 66 N m it lacked there, the plant's front tyres' forces gave 59); with it, 0.0006 (each
wheel's law at its load in the axles' sums as well over-corrects it: -0.0026).

A tyre does not build its force at once: its carcass deflects first, and the force follows
the slip angle with a first-order lag over the *relaxation length* ``sigma`` of road it rolls
(Pacejka 2012, section 7.2, ``sigma alpha'' + |V_x| alpha' = |V_x| alpha``, with ``alpha'``
the slip angle the force follows), a time ``tau = sigma / v`` of some 12 ms at 20 m/s. To
first order in ``tau`` (the lagged angle is the angle ``tau`` ago), each axle's law is
evaluated at::

    alpha'_i = alpha_i - tau_i alpha_i_dot / (1 + 4 q_i^2),   tau_i = sigma_i / v_s    (D3''')
    alpha_f_dot = delta_r - (a_t - r vx + l_f r') / v_s + (vy_a + l_f r) v_s' / v_s^2
    alpha_r_dot =         - (a_t - r vx - l_r r') / v_s + (vy_a - l_r r) v_s' / v_s^2

with ``delta_r`` the steering rate state, ``vy_a' = a_t - r vx`` (the roll axis does not sway),
and ``a_t``, ``r'`` those of the laws at the unlagged angles. The expansion holds while the
lag is short against the lateral mode's time, ``q_i = tau_i (C_f + C_r) / (m v_s)`` small
(0.06 on the sedan at 20 m/s, 1 at 5 m/s): the factor ``1 / (1 + 4 q^2)`` fades it out at
low speed, where the explicit form would otherwise overshoot (its product with the mode's
rate stays below 1/4). The relaxation lengths are the belief's
(``estimator.tyre_relaxation_length_front_m``, ``_rear_m``: the sedan's MF 6.1 tyres'
``K_ya / c_y`` at its static wheel loads, each axle's cornering-stiffness scale applied,
0.235 and 0.252 m, :func:`cosim.plant.tyre_model.relaxation_lengths_m`). Left out, the
model's lateral acceleration along a lane change's truth is 0.039 m/s^2 RMS off (0.15 at
most, where ``a_y`` reverses) and its yaw acceleration 0.0090 rad/s^2; with them 0.026 and
0.0049 (seed 8720). Both lengths 0: the laws at the slip angles themselves (the forces to
the bit; their derivatives, which CasADi then takes in another order, to rounding).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca

from cosim.core.physical_constants import GRAVITY_MPS2
from cosim.core.vehicle_equations import axle_slip_angles, saturating_axle_force
from cosim.core.vehicle_params import VehicleParams

MIN_LOAD_RATIO = 0.1
"""Smallest axle load over its static load that (D3'') takes (a wheelie is not modelled)."""

LOW_SPEED_MPS = 5.0
"""Below this forward speed the slip angles use :func:`slip_speed`'s floor, not vx."""

DEFAULT_CORNERING_STIFFNESS_FRONT_NPR = 72550.0
"""Front-axle cornering stiffness of the Pacejka sedan (``cosim identify``), used when the
belief (``VehicleParams``) does not carry one [N/rad]."""

DEFAULT_CORNERING_STIFFNESS_REAR_NPR = 79580.0
"""Rear-axle cornering stiffness of the Pacejka sedan (``cosim identify``) [N/rad]."""

TYRE_MODELS: tuple[str, ...] = ("saturating", "linear")
"""Tyre laws of the filters' bicycle: (D3) with or without the friction limit (D3')."""



@dataclass(frozen=True)
class RollParams:
    """The body roll mode the filters believe (R2): ``gradient_radpmps2`` steady roll per
    lateral acceleration, ``frequency_hz`` and ``damping_ratio`` of the mode,
    ``sway_arm_m`` the height of the CoG above the roll axis. A zero gradient and arm
    switch the mode off (the body then neither rolls nor sways)."""

    gradient_radpmps2: float = 0.0
    frequency_hz: float = 1.5
    damping_ratio: float = 0.5
    sway_arm_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("gradient_radpmps2", "sway_arm_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} = {value!r}: expected a finite number >= 0")
        for name in ("frequency_hz", "damping_ratio"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} = {value!r}: expected a positive finite number")

    @property
    def angular_frequency_radps(self) -> float:
        """omega = 2 pi f."""
        return 2.0 * math.pi * self.frequency_hz


@dataclass(frozen=True)
class BicycleParams:
    """The numbers of the dynamic bicycle the filters believe (SI; cornering stiffnesses per
    axle, both tyres; ``tyre_friction`` the peak friction coefficient, used by the
    ``saturating`` tyre law only)."""

    mass_kg: float
    yaw_inertia_kgm2: float
    cog_front_m: float
    cog_rear_m: float
    cornering_stiffness_front_npr: float
    cornering_stiffness_rear_npr: float
    tyre_friction: float = 1.0
    tyre_model: str = "saturating"
    roll: RollParams = RollParams()
    load_sensitivity_front: float = 0.0
    """``eps_f`` of (D3''): the front axle's cornering stiffness grows as its load to this
    power."""
    load_sensitivity_rear: float = 0.0
    """``eps_r`` of (D3''), the rear axle's."""
    load_transfer_height_m: float = 0.0
    """``h`` of (D3''), the CoG's height over the ground the pitch moment acts at (0: the
    axle loads stay static)."""
    relaxation_length_front_m: float = 0.0
    """``sigma_f`` of (D3'''): the road the front tyres roll while their force follows
    their slip angle (0: at once)."""
    relaxation_length_rear_m: float = 0.0
    """``sigma_r`` of (D3'''), the rear tyres'."""
    lateral_transfer_front_kg: float = 0.0
    """``m h (l_r / L) / t_f`` of (D3''''): the load each front wheel gains (the outer) or
    loses (the inner) per unit of lateral acceleration [N per m/s^2] (0: none)."""
    front_half_track_m: float = 0.0
    """``t_f / 2``: the arm of the front wheels' lateral forces' longitudinal components
    about the CoG, (D5') (0: none)."""
    lateral_transfer: bool = False
    """Whether the model has (D3'''') and (D5') at all: a model without them builds none of
    their operations (the filter's compiled step is then what it was without them)."""

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if name in ("tyre_model", "roll", "lateral_transfer"):
                continue
            if name in ("load_sensitivity_front", "load_sensitivity_rear",
                        "load_transfer_height_m", "relaxation_length_front_m",
                        "relaxation_length_rear_m", "lateral_transfer_front_kg",
                        "front_half_track_m"):
                if not (math.isfinite(value) and value >= 0.0):
                    raise ValueError(f"{name} = {value!r}: expected a finite number >= 0")
                continue
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} = {value!r}: expected a positive finite number")
        if self.tyre_model not in TYRE_MODELS:
            raise ValueError(
                f"tyre_model = {self.tyre_model!r}: expected one of {', '.join(TYRE_MODELS)}"
            )

    @property
    def axle_loads_n(self) -> tuple[float, float]:
        """Static vertical loads of the front and rear axle, ``m g l_r / L``, ``m g l_f / L``."""
        weight_n = self.mass_kg * GRAVITY_MPS2
        wheelbase_m = self.cog_front_m + self.cog_rear_m
        return weight_n * self.cog_rear_m / wheelbase_m, weight_n * self.cog_front_m / wheelbase_m

    @classmethod
    def from_vehicle(
        cls, belief: VehicleParams, tyre_model: str = "saturating", roll: RollParams | None = None,
        load_sensitivity: tuple[float, float] = (0.0, 0.0),
        relaxation_lengths_m: tuple[float, float] = (0.0, 0.0),
        lateral_transfer: bool = False,
    ) -> BicycleParams:
        """Mass, yaw inertia, CoG position, axle cornering stiffnesses and tyre friction of
        ``belief``; ``roll`` the body roll mode (none by default); ``load_sensitivity`` the
        ``(eps_f, eps_r)`` of (D3''), the load transfer at the belief's CoG height (both 0:
        none); ``relaxation_lengths_m`` the ``(sigma_f, sigma_r)`` of (D3''') (both 0: the
        forces follow the slip angles at once).

        ``VehicleParams`` gains ``cornering_stiffness_front_npr``/``_rear_npr``; a record
        without them gets :data:`DEFAULT_CORNERING_STIFFNESS_FRONT_NPR` and
        :data:`DEFAULT_CORNERING_STIFFNESS_REAR_NPR` (the identified Pacejka sedan).
        """
        return cls(
            mass_kg=belief.mass_kg,
            yaw_inertia_kgm2=belief.yaw_inertia_kgm2,
            cog_front_m=belief.cog_front_m,
            cog_rear_m=belief.cog_rear_m,
            cornering_stiffness_front_npr=float(getattr(
                belief, "cornering_stiffness_front_npr", DEFAULT_CORNERING_STIFFNESS_FRONT_NPR
            )),
            cornering_stiffness_rear_npr=float(getattr(
                belief, "cornering_stiffness_rear_npr", DEFAULT_CORNERING_STIFFNESS_REAR_NPR
            )),
            tyre_friction=belief.tyre_friction,
            tyre_model=tyre_model,
            roll=RollParams() if roll is None else roll,
            load_sensitivity_front=float(load_sensitivity[0]),
            load_sensitivity_rear=float(load_sensitivity[1]),
            load_transfer_height_m=belief.cog_height_m if any(load_sensitivity) else 0.0,
            relaxation_length_front_m=float(relaxation_lengths_m[0]),
            relaxation_length_rear_m=float(relaxation_lengths_m[1]),
            lateral_transfer=lateral_transfer,
            **(lateral_transfer_numbers(belief) if lateral_transfer else {}),
        )


def lateral_transfer_numbers(belief: VehicleParams) -> dict[str, float]:
    """The numbers of (D3'''') and (D5') for ``belief``: the roll moment ``m h a_y`` of the
    belief's CoG height over the ground, shared by the axles as their static loads (the
    front ``l_r / L``, as the wheel-speed model shares it: :func:`estimation.wheel_slip.
    wheel_load`), the front axle's share over its track."""
    track_front = belief.axle_tracks_m[0]
    wheelbase_m = belief.cog_front_m + belief.cog_rear_m
    moment_kgm = belief.mass_kg * belief.cog_height_m
    return {"lateral_transfer_front_kg": moment_kgm * belief.cog_rear_m / wheelbase_m
            / track_front,
            "front_half_track_m": 0.5 * track_front}


def slip_speed(vx_mps: ca.SX | float) -> ca.SX:
    """The forward speed the slip angles divide by: ``vx`` at and above
    :data:`LOW_SPEED_MPS` ``= v0``, ``v0/2 + vx^2/(2 v0)`` below (continuous with its first
    derivative, at least ``v0/2``)."""
    v0 = LOW_SPEED_MPS
    return ca.if_else(vx_mps >= v0, vx_mps, 0.5 * v0 + vx_mps**2 / (2.0 * v0))


def yaw_moment(front: ca.SX, rear: ca.SX, split: ca.SX | float, s: Mapping[str, ca.SX],
               bicycle: BicycleParams) -> ca.SX:
    """The yaw moment of the tyres' lateral forces about the CoG, (D5'): the axles',
    ``l_f F_yf - l_r F_yr``, and that of the front wheels' forces' longitudinal components,
    ``t_f / 2 sin(delta) (F_yfl - F_yfr)`` (``split``: left minus right) [N m]."""
    axles = bicycle.cog_front_m * front - bicycle.cog_rear_m * rear
    if not bicycle.lateral_transfer:
        return axles
    return axles + bicycle.front_half_track_m * ca.sin(s["steer_rad"]) * split


def axle_forces(s: Mapping[str, ca.SX],
                bicycle: BicycleParams) -> tuple[ca.SX, ca.SX, ca.SX | float]:
    """Lateral forces of the front and rear axle, (D1)-(D3) or (D1), (D2), (D3'), with the
    load transfer (D3'') and the tyres' relaxation (D3''') [N], and the front wheels' left
    minus right force, (D3'''')."""
    speed = slip_speed(s["vx_mps"])
    r = s["yaw_rate_radps"]
    axle_vy = axle_lateral_velocity(s, bicycle)
    alpha_front, alpha_rear = axle_slip_angles(  # (D1), (D2)
        axle_vy, r, s["steer_rad"], speed, bicycle.cog_front_m, bicycle.cog_rear_m)
    steady_front, steady_rear, steady_split = _tyre_laws(alpha_front, alpha_rear, s,
                                                         bicycle)
    # (D3'''): the laws at the slip angles a relaxation time ago, to first order, the
    # angles' rates from the steady forces.
    tyre_accel = ((steady_front + steady_rear) / bicycle.mass_kg
                  + s["lateral_accel_residual_mps2"])
    yaw_accel = yaw_moment(steady_front, steady_rear, steady_split, s,
                           bicycle) / bicycle.yaw_inertia_kgm2
    axle_vy_rate = tyre_accel - r * s["vx_mps"]
    speed_rate = (ca.if_else(s["vx_mps"] >= LOW_SPEED_MPS, 1.0, s["vx_mps"] / LOW_SPEED_MPS)
                  * (s["ax_mps2"] + r * s["vy_mps"]))
    alpha_front_rate = (s["steer_rate_radps"]
                        - (axle_vy_rate + bicycle.cog_front_m * yaw_accel) / speed
                        + (axle_vy + bicycle.cog_front_m * r) * speed_rate / speed**2)
    alpha_rear_rate = (-(axle_vy_rate - bicycle.cog_rear_m * yaw_accel) / speed
                       + (axle_vy - bicycle.cog_rear_m * r) * speed_rate / speed**2)
    mode_rate = (bicycle.cornering_stiffness_front_npr
                 + bicycle.cornering_stiffness_rear_npr) / (bicycle.mass_kg * speed)
    lag_front = _faded_lag(bicycle.relaxation_length_front_m / speed, mode_rate)
    lag_rear = _faded_lag(bicycle.relaxation_length_rear_m / speed, mode_rate)
    return _tyre_laws(alpha_front - lag_front * alpha_front_rate,
                      alpha_rear - lag_rear * alpha_rear_rate, s, bicycle)


def _faded_lag(lag_s: ca.SX, mode_rate_1ps: ca.SX) -> ca.SX:
    """``tau / (1 + 4 q^2)`` with ``q = tau * mode_rate``: the relaxation time (D3''') takes,
    faded out where it is not short against the lateral mode's time [s]."""
    q = lag_s * mode_rate_1ps
    return lag_s / (1.0 + 4.0 * q * q)


def _axle_law(stiffness: ca.SX, alpha: ca.SX, ratio: ca.SX, sensitivity: ca.SX,
              static_n: ca.SX, bicycle: BicycleParams) -> ca.SX:
    """An axle's (or, with half its stiffness and load, a wheel's) force at slip angle
    ``alpha`` and load ratio ``ratio``, (D3) or (D3') with (D3'') [N]."""
    linear = stiffness * alpha * ratio**sensitivity  # (D3)
    if bicycle.tyre_model == "linear":
        return linear
    # (D3'): the linear tyre up to a smooth limit at the friction force of the load.
    return saturating_axle_force(linear, bicycle.tyre_friction * static_n * ratio)


def _tyre_laws(alpha_front: ca.SX, alpha_rear: ca.SX, s: Mapping[str, ca.SX],
               bicycle: BicycleParams) -> tuple[ca.SX, ca.SX, ca.SX | float]:
    """Each axle's force at the slip angle it follows, (D3) or (D3'), with (D3''), and the
    front wheels' left minus right force, (D3'''') [N]."""
    # (D3''): the pitch moment m a_x h moves the load m a_x h / L from the front axle to
    # the rear; each axle's stiffness (and friction force) follows its load ratio.
    static_front, static_rear = bicycle.axle_loads_n
    transfer = (bicycle.mass_kg * s["ax_mps2"] * bicycle.load_transfer_height_m
                / (bicycle.cog_front_m + bicycle.cog_rear_m))
    ratio_front = ca.fmax(1.0 - transfer / static_front, MIN_LOAD_RATIO)
    ratio_rear = ca.fmax(1.0 + transfer / static_rear, MIN_LOAD_RATIO)
    front = _axle_law(bicycle.cornering_stiffness_front_npr, alpha_front, ratio_front,
                      bicycle.load_sensitivity_front, static_front, bicycle)
    rear = _axle_law(bicycle.cornering_stiffness_rear_npr, alpha_rear, ratio_rear,
                     bicycle.load_sensitivity_rear, static_rear, bicycle)
    if not bicycle.lateral_transfer:
        return front, rear, 0.0
    # (D3''''): the roll moment moves load from the inner front wheel to the outer one,
    # each with half the axle's law at its own load; the lateral acceleration taken as the
    # turn's, r vx, held within what the road gives, mu g (a sigma point or a prior far off,
    # a yaw rate no tyre gives, moves no more load than the grip can).
    grip = bicycle.tyre_friction * GRAVITY_MPS2
    lateral = ca.fmin(ca.fmax(s["yaw_rate_radps"] * s["vx_mps"], -grip), grip)
    shift = 2.0 * bicycle.lateral_transfer_front_kg * lateral / static_front
    left, right = (
        _axle_law(0.5 * bicycle.cornering_stiffness_front_npr, alpha_front,
                  ca.fmax(ratio_front + side * shift, MIN_LOAD_RATIO),
                  bicycle.load_sensitivity_front, 0.5 * static_front, bicycle)
        for side in (-1.0, 1.0))
    return front, rear, left - right


def axle_lateral_velocity(s: Mapping[str, ca.SX], bicycle: BicycleParams) -> ca.SX:
    """Lateral velocity of the roll axis below the CoG, in the vehicle frame, (R1) [m/s]."""
    return s["vy_mps"] + bicycle.roll.sway_arm_m * s["roll_rate_radps"]


Forces = tuple[ca.SX, ca.SX, ca.SX | float]
"""The front and the rear axle's lateral force of :func:`axle_forces` and the front wheels'
left minus right force [N]."""


def lateral_tyre_accel(s: Mapping[str, ca.SX], bicycle: BicycleParams,
                       forces: Forces | None = None) -> ca.SX:
    """Lateral acceleration the tyres give the car, ``a_t``: their force per unit mass plus
    the residual state [m/s^2] (``forces``: the axles' forces at ``s``, if already built)."""
    force_front, force_rear, _ = axle_forces(s, bicycle) if forces is None else forces
    return (force_front + force_rear) / bicycle.mass_kg + s["lateral_accel_residual_mps2"]


def roll_accel(s: Mapping[str, ca.SX], bicycle: BicycleParams,
               forces: Forces | None = None) -> ca.SX:
    """Roll acceleration of the body, (R2) without noise [rad/s^2]."""
    roll = bicycle.roll
    omega = roll.angular_frequency_radps
    target = roll.gradient_radpmps2 * lateral_tyre_accel(s, bicycle, forces)
    return (
        -omega**2 * (s["roll_rad"] - target)
        - 2.0 * roll.damping_ratio * omega * s["roll_rate_radps"]
    )


def world_velocity(s: Mapping[str, ca.SX]) -> tuple[ca.SX, ca.SX]:
    """East and north velocity of the CoG, the vehicle-frame ``(vx, vy)`` turned by the
    heading, (D6) [m/s]."""
    cos_yaw, sin_yaw = ca.cos(s["yaw_rad"]), ca.sin(s["yaw_rad"])
    return (s["vx_mps"] * cos_yaw - s["vy_mps"] * sin_yaw,
            s["vx_mps"] * sin_yaw + s["vy_mps"] * cos_yaw)


def cog_lateral_accel(s: Mapping[str, ca.SX], bicycle: BicycleParams,
                      forces: Forces | None = None) -> ca.SX:
    """Kinematic lateral acceleration of the CoG, ``vy' + r vx = a_t - h p'``: what an IMU
    at the CoG measures [m/s^2]. The axles' forces are built once for both terms."""
    forces = axle_forces(s, bicycle) if forces is None else forces
    return (lateral_tyre_accel(s, bicycle, forces)
            - bicycle.roll.sway_arm_m * roll_accel(s, bicycle, forces))
