"""The dynamic bicycle as CasADi expressions (Rajamani 2012, sec. 2.3), with linear tyres or
tyres that saturate at the friction force.

Lateral state ``[vy_mps, yaw_rate_radps]``: lateral velocity of the centre of gravity (CoG)
and yaw rate, both in the vehicle frame (ISO 8855: x forward, y left, z up; yaw
counter-clockwise positive). Input ``steer_rad``: front road-wheel angle, positive to the
left. The forward speed ``vx_mps`` is a scheduling variable of the lateral model. For
simulation the state is extended to ``[x_m, y_m, yaw_rad, vx_mps, vy_mps, yaw_rate_radps]``
(position of the CoG in the world frame, ENU) with the inputs ``[accel_mps2, steer_rad]``,
where ``accel_mps2`` is ``vx'`` (the longitudinal input).

Parameters ``[mass_kg, yaw_inertia_kgm2, cog_front_m, cog_rear_m,
cornering_stiffness_front_npr, cornering_stiffness_rear_npr]`` (:data:`PARAM_NAMES`) are an
input of every Function, so one Function serves a controller (numbers) and system
identification (symbols, exact Jacobians). The cornering stiffnesses are per *axle* (both
tyres): Rajamani writes ``2 C_alpha`` for the same quantity.

Equations (Rajamani, "Vehicle Dynamics and Control", 2nd ed., ch. 2,
the bicycle model of lateral vehicle dynamics), small angles::

    alpha_f = delta - (vy + l_f r) / vx                                   (D1)
    alpha_r = -(vy - l_r r) / vx                                          (D2)
    F_yf = C_f alpha_f,   F_yr = C_r alpha_r                              (D3)
    vy'  = (F_yf + F_yr) / m - vx r                                       (D4)
    r'   = (l_f F_yf - l_r F_yr) / I_z                                    (D5)
    x' = vx cos(yaw) - vy sin(yaw),  y' = vx sin(yaw) + vy cos(yaw),
    yaw' = r,  vx' = a                                                    (D6)

With a friction ``mu`` given (a controller that knows the road is wet, ``tracker.grip``) each
axle's force saturates smoothly at the friction force of its static load, (D3') of
:mod:`cosim.core.vehicle_equations` (the filter's law, :mod:`estimation.bicycle`)::

    F_zf = m g l_r / L,  F_zr = m g l_f / L
    F_yi = mu F_zi tanh(C_i alpha_i / (mu F_zi))                          (D3')

the same stiffness at small slip, at most ``mu F_zi``. The linear tyres (D3) promise any
force: near the limit they promise more than the road gives (at 70 % of ``mu F_z`` by (D3),
(D3') gives 60 %), and a controller that believes them steers too little, too late.

(D4)-(D5) are the state-space form ``vy' = a11 vy + a12 r + b11 delta``, ``r' = a21 vy + a22 r +
b21 delta`` (:meth:`DynamicBicycleParams.lateral_state_space`).

Steady-state cornering (Rajamani ch. 3, steady-state steering and the understeer gradient):
with ``L = l_f + l_r``, the understeer gradient

    K = (m / L) (l_r / C_f - l_f / C_r)          [rad per m/s^2]          (S1)

gives the steering of a steady turn ``delta = L / R + K a_y`` and hence the yaw-rate gain

    r / delta = vx / (L + K vx^2) = (vx / L) / (1 + K_g vx^2 / (g L))     (S2)

where ``K_g = K g`` is the same gradient in rad per g (a form of (S2) often printed needs K in
rad/g, not rad/(m/s^2)). The lateral velocity of the steady turn follows from the rear
axle's share of the centripetal force, ``F_yr = m vx r l_f / L``, and (D2):

    vy = r (l_r - m l_f vx^2 / (L C_r))                                   (S3)

With the saturating tyres (D3') both axles use the same share ``u = a_y / (mu g)`` of their
grip in a steady turn (each carries its static load's share of ``m a_y``), so each slip angle
is ``(mu F_zi / C_i) atanh(u)`` and the steering of the steady turn is

    delta = L / R + K mu g atanh(a_y / (mu g))                            (S4)

which is (S1)'s ``L / R + K a_y`` where the tyres barely slip and grows without bound as
``a_y`` nears ``mu g`` (held at :data:`MAX_STEADY_USAGE` of it).

(D1)-(D6) and (S1)-(S3) are written with plain arithmetic and CasADi's ``sin``/``cos``, so
they accept CasADi symbols as well as floats.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType

import casadi as ca
import numpy as np

from cosim.core.exceptions import ConfigError
from cosim.core.physical_constants import GRAVITY_MPS2
from cosim.core.vehicle_equations import axle_slip_angles, rk4_step, saturating_axle_force
from cosim.core.vehicle_params import VehicleParams

LATERAL_STATE_NAMES: tuple[str, ...] = ("vy_mps", "yaw_rate_radps")
"""State of the lateral model, in vector order."""

STATE_NAMES: tuple[str, ...] = ("x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "yaw_rate_radps")
"""State of the full (simulation) model, in vector order."""

INPUT_NAMES: tuple[str, ...] = ("accel_mps2", "steer_rad")
"""Inputs of the full model, in vector order (the lateral model takes ``steer_rad`` alone)."""

PARAM_NAMES: tuple[str, ...] = (
    "mass_kg",
    "yaw_inertia_kgm2",
    "cog_front_m",
    "cog_rear_m",
    "cornering_stiffness_front_npr",
    "cornering_stiffness_rear_npr",
)
"""Parameters of the model, in vector order (stiffnesses per axle, N/rad)."""

LATERAL_STATE = MappingProxyType({name: i for i, name in enumerate(LATERAL_STATE_NAMES)})
"""Read-only map from lateral state name to its index."""

STATE = MappingProxyType({name: i for i, name in enumerate(STATE_NAMES)})
"""Read-only map from state name to its index in the full state vector."""

INPUT = MappingProxyType({name: i for i, name in enumerate(INPUT_NAMES)})
"""Read-only map from input name to its index in the input vector."""

PARAM = MappingProxyType({name: i for i, name in enumerate(PARAM_NAMES)})
"""Read-only map from parameter name to its index in the parameter vector."""

Symbolic = ca.SX | ca.MX | ca.DM


@dataclass(frozen=True)
class DynamicBicycleParams:
    """Numbers of the linear-tyre dynamic bicycle (SI; stiffnesses per axle)."""

    mass_kg: float
    yaw_inertia_kgm2: float
    cog_front_m: float
    cog_rear_m: float
    cornering_stiffness_front_npr: float
    cornering_stiffness_rear_npr: float

    def __post_init__(self) -> None:
        for name in PARAM_NAMES:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ConfigError(f"DynamicBicycleParams.{name} = {value!r}: expected a "
                                  "positive finite number")

    @classmethod
    def from_vehicle(cls, vehicle: VehicleParams, cornering_stiffness_front_npr: float,
                     cornering_stiffness_rear_npr: float) -> DynamicBicycleParams:
        """Mass, yaw inertia and CoG position of ``vehicle`` plus the two axle cornering
        stiffnesses."""
        return cls(
            mass_kg=vehicle.mass_kg,
            yaw_inertia_kgm2=vehicle.yaw_inertia_kgm2,
            cog_front_m=vehicle.cog_front_m,
            cog_rear_m=vehicle.cog_rear_m,
            cornering_stiffness_front_npr=cornering_stiffness_front_npr,
            cornering_stiffness_rear_npr=cornering_stiffness_rear_npr,
        )

    def as_vector(self) -> np.ndarray:
        """The parameter vector in :data:`PARAM_NAMES` order (the Functions' ``params``)."""
        return np.array([float(getattr(self, name)) for name in PARAM_NAMES])

    @property
    def wheelbase_m(self) -> float:
        """L = l_f + l_r [m]."""
        return self.cog_front_m + self.cog_rear_m

    @property
    def understeer_gradient_radpmps2(self) -> float:
        """K of (S1) [rad per m/s^2]; > 0 understeer, < 0 oversteer."""
        return float(understeer_gradient(self.as_vector()))

    @property
    def understeer_gradient_degpg(self) -> float:
        """K of (S1) in degrees of steering per g of lateral acceleration [deg/g]."""
        return radpmps2_to_degpg(self.understeer_gradient_radpmps2)

    def yaw_rate_gain_per_s(self, vx_mps: float) -> float:
        """Steady-state yaw-rate gain r/delta of (S2) at forward speed ``vx_mps`` [1/s]."""
        return float(steady_yaw_rate_gain(vx_mps, self.as_vector()))

    def steady_state(self, vx_mps: float, steer_rad: float) -> dict[str, float]:
        """The steady turn at ``vx_mps`` and ``steer_rad``: ``vy_mps``, ``yaw_rate_radps``
        (S2, S3) and ``ay_mps2 = vx r``."""
        yaw_rate = self.yaw_rate_gain_per_s(vx_mps) * steer_rad
        vy = float(steady_lateral_velocity(vx_mps, yaw_rate, self.as_vector()))
        return {"vy_mps": vy, "yaw_rate_radps": yaw_rate, "ay_mps2": vx_mps * yaw_rate}

    def lateral_state_space(self, vx_mps: float) -> tuple[np.ndarray, np.ndarray]:
        """``(A, B)`` of ``[vy, r]' = A [vy, r] + B delta`` at ``vx_mps`` (a11 ...
        b21), rows and columns in :data:`LATERAL_STATE_NAMES` order."""
        if not (math.isfinite(vx_mps) and vx_mps > 0.0):
            raise ConfigError(f"vx_mps = {vx_mps!r}: expected a positive forward speed")
        m, i_z = self.mass_kg, self.yaw_inertia_kgm2
        l_f, l_r = self.cog_front_m, self.cog_rear_m
        c_f, c_r = self.cornering_stiffness_front_npr, self.cornering_stiffness_rear_npr
        vy, r = LATERAL_STATE["vy_mps"], LATERAL_STATE["yaw_rate_radps"]
        a = np.zeros((2, 2))
        b = np.zeros((2, 1))
        a[vy, vy] = -(c_f + c_r) / (m * vx_mps)  # a11
        a[vy, r] = (l_r * c_r - l_f * c_f) / (m * vx_mps) - vx_mps  # a12
        a[r, vy] = (l_r * c_r - l_f * c_f) / (i_z * vx_mps)  # a21
        a[r, r] = -(l_f**2 * c_f + l_r**2 * c_r) / (i_z * vx_mps)  # a22
        b[vy, 0] = c_f / m  # b11
        b[r, 0] = l_f * c_f / i_z  # b21
        return a, b


MAX_STEADY_USAGE = 0.95
"""The largest share of the grip (S4) is evaluated at: no steady turn exists at ``mu g``
(``atanh(1)`` is infinite), and a reference asking more gets the steering of 95 %."""


def steady_understeer_rad(gradient_radpmps2: float, speed_mps: np.ndarray,
                          curvature_1pm: np.ndarray,
                          grip_mps2: float | None = None) -> np.ndarray:
    """The steering a steady turn of ``a_y = v^2 kappa`` needs beyond the kinematic ``L / R``
    [rad]: ``K a_y`` of (S1) with linear tyres (``grip_mps2`` None), ``K mu g atanh(a_y /
    (mu g))`` of (S4) with tyres that saturate at ``grip_mps2 = mu g``."""
    if grip_mps2 is None:
        return gradient_radpmps2 * speed_mps**2 * curvature_1pm
    usage = np.clip(speed_mps**2 * curvature_1pm / grip_mps2, -MAX_STEADY_USAGE,
                    MAX_STEADY_USAGE)
    return gradient_radpmps2 * grip_mps2 * np.arctanh(usage)


def radpmps2_to_degpg(gradient_radpmps2: float) -> float:
    """A gradient in rad per m/s^2 expressed in degrees per g."""
    return math.degrees(gradient_radpmps2) * GRAVITY_MPS2


def _param(params: Symbolic | np.ndarray, name: str) -> Symbolic:
    return params[PARAM[name]]


def understeer_gradient(params: Symbolic | np.ndarray) -> Symbolic:
    """K of (S1) [rad per m/s^2] from the parameter vector."""
    m = _param(params, "mass_kg")
    l_f, l_r = _param(params, "cog_front_m"), _param(params, "cog_rear_m")
    c_f = _param(params, "cornering_stiffness_front_npr")
    c_r = _param(params, "cornering_stiffness_rear_npr")
    return m / (l_f + l_r) * (l_r / c_f - l_f / c_r)


def steady_yaw_rate_gain(vx_mps: Symbolic | float, params: Symbolic | np.ndarray) -> Symbolic:
    """Steady-state yaw-rate gain r/delta of (S2) [1/s]."""
    wheelbase = _param(params, "cog_front_m") + _param(params, "cog_rear_m")
    return vx_mps / (wheelbase + understeer_gradient(params) * vx_mps**2)


def steady_lateral_velocity(vx_mps: Symbolic | float, yaw_rate_radps: Symbolic | float,
                            params: Symbolic | np.ndarray) -> Symbolic:
    """Lateral velocity of the CoG in a steady turn of yaw rate ``yaw_rate_radps``, (S3)."""
    m = _param(params, "mass_kg")
    l_f, l_r = _param(params, "cog_front_m"), _param(params, "cog_rear_m")
    c_r = _param(params, "cornering_stiffness_rear_npr")
    return yaw_rate_radps * (l_r - m * l_f * vx_mps**2 / ((l_f + l_r) * c_r))


def slip_angles(lateral_state: Symbolic, steer_rad: Symbolic, vx_mps: Symbolic,
                params: Symbolic, min_slip_speed_mps: float = 0.0) -> tuple[Symbolic, Symbolic]:
    """Front and rear axle slip angles, (D1)-(D2) [rad].

    With ``min_slip_speed_mps > 0`` the speed in the denominators is ``fmax(vx,
    min_slip_speed_mps)``: (D1)-(D2) are singular at standstill, and a controller's model
    must stay finite (and not too stiff) at any speed its optimiser tries.
    """
    vy = lateral_state[LATERAL_STATE["vy_mps"]]
    r = lateral_state[LATERAL_STATE["yaw_rate_radps"]]
    l_f, l_r = _param(params, "cog_front_m"), _param(params, "cog_rear_m")
    if min_slip_speed_mps > 0.0:
        vx_mps = ca.fmax(vx_mps, min_slip_speed_mps)
    return axle_slip_angles(vy, r, steer_rad, vx_mps, l_f, l_r)


def static_axle_loads_n(params: Symbolic | np.ndarray) -> tuple[Symbolic, Symbolic]:
    """``F_zf = m g l_r / L`` and ``F_zr = m g l_f / L``, the axles' static loads [N]."""
    weight = _param(params, "mass_kg") * GRAVITY_MPS2
    l_f, l_r = _param(params, "cog_front_m"), _param(params, "cog_rear_m")
    return weight * l_r / (l_f + l_r), weight * l_f / (l_f + l_r)


def lateral_dynamics(lateral_state: Symbolic, steer_rad: Symbolic, vx_mps: Symbolic,
                     params: Symbolic, min_slip_speed_mps: float = 0.0,
                     friction: Symbolic | float | None = None) -> Symbolic:
    """``[vy', r']`` of (D1)-(D5) as a 2x1 expression (``vx_mps`` must be positive unless
    ``min_slip_speed_mps > 0`` guards the slip angles, see :func:`slip_angles`); with a
    ``friction`` the tyres saturate, (D3'), else they are linear, (D3)."""
    r = lateral_state[LATERAL_STATE["yaw_rate_radps"]]
    alpha_f, alpha_r = slip_angles(lateral_state, steer_rad, vx_mps, params,
                                   min_slip_speed_mps)
    force_front = _param(params, "cornering_stiffness_front_npr") * alpha_f  # (D3)
    force_rear = _param(params, "cornering_stiffness_rear_npr") * alpha_r
    if friction is not None:  # (D3')
        load_front, load_rear = static_axle_loads_n(params)
        force_front = saturating_axle_force(force_front, friction * load_front)
        force_rear = saturating_axle_force(force_rear, friction * load_rear)
    derivative = {
        "vy_mps": (force_front + force_rear) / _param(params, "mass_kg") - vx_mps * r,
        "yaw_rate_radps": (_param(params, "cog_front_m") * force_front
                           - _param(params, "cog_rear_m") * force_rear)
        / _param(params, "yaw_inertia_kgm2"),
    }
    return ca.vertcat(*(derivative[name] for name in LATERAL_STATE_NAMES))


def continuous_dynamics(state: Symbolic, inputs: Symbolic, params: Symbolic,
                        min_slip_speed_mps: float = 0.0,
                        friction: Symbolic | float | None = None) -> Symbolic:
    """Time derivative of the full state, (D1)-(D6), as a 6x1 expression
    (``min_slip_speed_mps``: see :func:`slip_angles`; ``friction``: :func:`lateral_dynamics`)."""
    yaw = state[STATE["yaw_rad"]]
    vx = state[STATE["vx_mps"]]
    vy = state[STATE["vy_mps"]]
    r = state[STATE["yaw_rate_radps"]]
    lateral = lateral_dynamics(ca.vertcat(vy, r), inputs[INPUT["steer_rad"]], vx, params,
                               min_slip_speed_mps, friction)
    derivative = {
        "x_m": vx * ca.cos(yaw) - vy * ca.sin(yaw),
        "y_m": vx * ca.sin(yaw) + vy * ca.cos(yaw),
        "yaw_rad": r,
        "vx_mps": inputs[INPUT["accel_mps2"]],
        "vy_mps": lateral[LATERAL_STATE["vy_mps"]],
        "yaw_rate_radps": lateral[LATERAL_STATE["yaw_rate_radps"]],
    }
    return ca.vertcat(*(derivative[name] for name in STATE_NAMES))


def _check_step(dt_s: float, substeps: int) -> None:
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise ConfigError(f"dt_s = {dt_s!r}: expected a positive step")
    if not (isinstance(substeps, int) and substeps >= 1):
        raise ConfigError(f"substeps = {substeps!r}: expected an integer >= 1")


def lateral_function() -> ca.Function:
    """``f(lateral_state, steer_rad, vx_mps, params) -> lateral_state_dot``, (D1)-(D5)."""
    state = ca.SX.sym("lateral_state", len(LATERAL_STATE_NAMES))
    steer = ca.SX.sym("steer_rad")
    vx = ca.SX.sym("vx_mps")
    params = ca.SX.sym("params", len(PARAM_NAMES))
    return ca.Function(
        "dynamic_bicycle_lateral",
        [state, steer, vx, params],
        [lateral_dynamics(state, steer, vx, params)],
        ["lateral_state", "steer_rad", "vx_mps", "params"],
        ["lateral_state_dot"],
    )


def lateral_discrete_function(dt_s: float, substeps: int = 1) -> ca.Function:
    """``F(lateral_state, steer_rad, vx_mps, params) -> next_lateral_state`` over ``dt_s``
    by ``substeps`` RK4 steps, steer and speed held."""
    _check_step(dt_s, substeps)
    state = ca.SX.sym("lateral_state", len(LATERAL_STATE_NAMES))
    steer = ca.SX.sym("steer_rad")
    vx = ca.SX.sym("vx_mps")
    params = ca.SX.sym("params", len(PARAM_NAMES))
    h = dt_s / substeps
    next_state = state
    for _ in range(substeps):
        next_state = rk4_step(lambda s: lateral_dynamics(s, steer, vx, params), next_state, h)
    return ca.Function(
        "dynamic_bicycle_lateral_rk4",
        [state, steer, vx, params],
        [next_state],
        ["lateral_state", "steer_rad", "vx_mps", "params"],
        ["next_lateral_state"],
    )


def continuous_function() -> ca.Function:
    """``f(state, inputs, params) -> state_dot``, (D1)-(D6); callable with numpy arrays
    (``np.asarray(f(x, u, p))``)."""
    state = ca.SX.sym("state", len(STATE_NAMES))
    inputs = ca.SX.sym("inputs", len(INPUT_NAMES))
    params = ca.SX.sym("params", len(PARAM_NAMES))
    return ca.Function(
        "dynamic_bicycle",
        [state, inputs, params],
        [continuous_dynamics(state, inputs, params)],
        ["state", "inputs", "params"],
        ["state_dot"],
    )


def discrete_function(dt_s: float, substeps: int = 1) -> ca.Function:
    """``F(state, inputs, params) -> next_state`` over ``dt_s`` by ``substeps`` RK4 steps."""
    _check_step(dt_s, substeps)
    state = ca.SX.sym("state", len(STATE_NAMES))
    inputs = ca.SX.sym("inputs", len(INPUT_NAMES))
    params = ca.SX.sym("params", len(PARAM_NAMES))
    h = dt_s / substeps
    next_state = state
    for _ in range(substeps):
        next_state = rk4_step(lambda s: continuous_dynamics(s, inputs, params), next_state, h)
    return ca.Function(
        "dynamic_bicycle_rk4",
        [state, inputs, params],
        [next_state],
        ["state", "inputs", "params"],
        ["next_state"],
    )
