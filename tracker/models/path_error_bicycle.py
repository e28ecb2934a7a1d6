"""The linear-tyre dynamic bicycle in path coordinates, for the ``dynamic-mpc`` tracker.

The ``dynamic-mpc`` design tracks a curved path with a dynamic bicycle whose position is
expressed as errors from the path, not as world coordinates (Rajamani, "Vehicle Dynamics
and Control", 2nd ed., Springer 2012, sec. 2.5). Its state is
``[v_y, psi, v_x, v_x', e1, e2]``; it is often printed with ``psi``, but the
lateral dynamics and ``e2' = psi_D' - psi'`` need the yaw *rate*, and the yaw angle itself
enters nothing once the errors are relative to the path, so the state here is
:data:`STATE_NAMES`::

    [vy_mps, yaw_rate_radps, vx_mps, ax_mps2, e1_m, e2_rad]

with inputs :data:`INPUT_NAMES` ``[accel_mps2, steer_rad]`` (the commanded longitudinal
acceleration and front road-wheel angle) and outputs :data:`OUTPUT_NAMES`
``[vx_mps, e1_m, e2_rad]`` (the reference design's ``Y``).

Sign conventions (ISO 8855, as everywhere in the testbed): ``e1`` is the lateral offset of
the centre of gravity from the path, positive when the car is *left* of it (what
:meth:`tracker.paths.reference_path.ReferencePath.project` returns); ``e2 = yaw - path_yaw`` is
positive when the car points left of the path's tangent; steering is positive to the left.
The reference design measures both errors the other way (``e1`` positive right, ``e2 = psi_D -
psi``), hence its ``e1' = v_x e2 - v_y`` and ``e2' = psi_D' - psi'``: negating both errors turns its
equations into (P5)-(P6) below, nothing else changes.

Equations, at the speed ``v0`` the model is linearised at (the reference design's LPV approach: the
current estimated ``v_x``, held over the horizon), with ``a11 ... b21`` the dynamic
bicycle's lateral coefficients at ``v0``
(:meth:`tracker.models.dynamic_bicycle.DynamicBicycleParams.lateral_state_space`, built here
from :func:`tracker.models.dynamic_bicycle.lateral_dynamics`, the same (D1)-(D5), not
re-derived)::

    vy' = a11 vy + a12 r + b11 delta                                       (P1)
    r'  = a21 vy + a22 r + b21 delta                                       (P2)
    vx' = ax                                                               (P3)
    ax' = (a_cmd - ax) / tau_a                                             (P4)
    e1' = v0 e2 + vy                                                       (P5)
    e2' = r - psi_D'                                                       (P6)
    psi_D' = vx kappa(s)                                                   (P7)

(P5)-(P6) are the small-angle form of the exact path kinematics ``e1' = vx sin e2 +
vy cos e2``, ``e2' = r - kappa s'`` with ``s' = (vx cos e2 - vy sin e2) / (1 - kappa
e1)``. (P4) is the reference design's first-order lag on the acceleration "with the sample time":
``tau_a`` is :attr:`PathErrorParams.accel_time_constant_s` (the tracker's default is the
reference design's Ts). (P7), the desired yaw rate, is an input of the model
(``yaw_rate_ref_radps``, held over a stage): the tracker evaluates it from the path's curvature at
the arc lengths the car is expected to reach.

For a given ``v0`` the model is linear: ``x' = A(v0) x + B(v0) u + E psi_D'``. The slip
angles inside (P1)-(P2) divide by ``v0``; like the world-frame models
(:func:`tracker.models.dynamic_bicycle.slip_angles`) they use ``max(v0, v_low)``, so the model stays
finite and not too stiff at low speed. The model is meant for cruising speeds: below
``v_low`` it turns at ``v_low delta / L`` instead of the kinematic ``v0 delta / L``.

Discretisation: the reference design uses forward Euler. At ``Ts = 0.1 s`` Euler is unstable for the
default sedan below 5.2 m/s (lateral eigenvalues beyond ``-2/Ts``) and wrong in phase at
cruising speed (at 20 m/s the lateral modes turn by 0.63 rad per stage instead of the
exact 0.36); with ``tau_a = Ts`` it also turns (P4) into a pure one-stage delay,
``ax(k+1) = a_cmd(k)``. Here the stage map is classical RK4 with :func:`rk4_substeps`
steps, so that ``h |lambda| <= 0.5`` for every eigenvalue down to ``v_low``; for a linear
system with the inputs held this is the exact zero-order-hold discretisation
``exp(A Ts)`` up to its fifth Taylor term per substep (relative error below 3e-4 per
substep in the fastest mode), stable at any speed, and it stays a CasADi expression in
``v0``, so the QP is built once with ``v0`` as a parameter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType

import casadi as ca
import numpy as np

from cosim.core.exceptions import ConfigError
from cosim.core.vehicle_equations import rk4_step
from cosim.core.vehicle_params import VehicleParams
from tracker.models import dynamic_bicycle as bicycle

STATE_NAMES: tuple[str, ...] = ("vy_mps", "yaw_rate_radps", "vx_mps", "ax_mps2", "e1_m",
                                "e2_rad")
"""State of the path-error model (yaw rate for the printed form's psi), in order."""

INPUT_NAMES: tuple[str, ...] = ("accel_mps2", "steer_rad")
"""Inputs: commanded acceleration and front road-wheel angle (the Command fields), in order."""

OUTPUT_NAMES: tuple[str, ...] = ("vx_mps", "e1_m", "e2_rad")
"""The reference design's outputs ``Y = [v_x, e1, e2]``, in order."""

STATE = MappingProxyType({name: i for i, name in enumerate(STATE_NAMES)})
"""Read-only map from state name to its index in the state vector."""

INPUT = MappingProxyType({name: i for i, name in enumerate(INPUT_NAMES)})
"""Read-only map from input name to its index in the input vector."""

OUTPUT = MappingProxyType({name: i for i, name in enumerate(OUTPUT_NAMES)})
"""Read-only map from output name to its index in the output vector."""

SUBSTEP_LIMIT = 0.5
"""Largest ``h |lambda|`` of an RK4 substep (accuracy, not only stability: RK4's amplification
at ``-0.5`` is within 3e-4 of ``exp(-0.5)``)."""

Symbolic = ca.SX | ca.MX | ca.DM


@dataclass(frozen=True)
class PathErrorParams:
    """Numbers of the path-error model: the bicycle, the acceleration lag, the speed guard."""

    bicycle: bicycle.DynamicBicycleParams
    accel_time_constant_s: float
    """tau_a of (P4): lag of the achieved acceleration behind the command [s]."""
    low_speed_mps: float = 4.0
    """v_low: the slip angles of (P1)-(P2) divide by ``max(v0, v_low)`` [m/s]."""

    def __post_init__(self) -> None:
        tau = self.accel_time_constant_s
        if not (math.isfinite(tau) and tau > 0.0):
            raise ConfigError(f"accel_time_constant_s = {tau!r}: expected a positive time")
        if not (math.isfinite(self.low_speed_mps) and self.low_speed_mps > 0.0):
            raise ConfigError(f"low_speed_mps = {self.low_speed_mps!r}: expected a positive "
                              "speed")

    @classmethod
    def from_vehicle(cls, vehicle: VehicleParams,
                     accel_time_constant_s: float) -> PathErrorParams:
        """The belief ``vehicle`` (mass, yaw inertia, CoG position, axle cornering
        stiffnesses) with the acceleration lag ``accel_time_constant_s``."""
        return cls(
            bicycle=bicycle.DynamicBicycleParams.from_vehicle(
                vehicle,
                vehicle.cornering_stiffness_front_npr,
                vehicle.cornering_stiffness_rear_npr,
            ),
            accel_time_constant_s=accel_time_constant_s,
        )


def continuous_dynamics(state: Symbolic, inputs: Symbolic, speed_mps: Symbolic,
                        yaw_rate_ref_radps: Symbolic, params: PathErrorParams) -> Symbolic:
    """Time derivative of the state, (P1)-(P6), linearised at ``speed_mps`` (v0), with
    the desired yaw rate ``yaw_rate_ref_radps`` (P7); a 6x1 expression."""
    vy = state[STATE["vy_mps"]]
    r = state[STATE["yaw_rate_radps"]]
    by_name = {"vy_mps": vy, "yaw_rate_radps": r}
    lateral_state = ca.vertcat(*(by_name[name] for name in bicycle.LATERAL_STATE_NAMES))
    lateral = bicycle.lateral_dynamics(lateral_state, inputs[INPUT["steer_rad"]], speed_mps,
                                       params.bicycle.as_vector(), params.low_speed_mps)
    derivative = {
        "vy_mps": lateral[bicycle.LATERAL_STATE["vy_mps"]],  # (P1)
        "yaw_rate_radps": lateral[bicycle.LATERAL_STATE["yaw_rate_radps"]],  # (P2)
        "vx_mps": state[STATE["ax_mps2"]],  # (P3)
        "ax_mps2": (inputs[INPUT["accel_mps2"]] - state[STATE["ax_mps2"]])
        / params.accel_time_constant_s,  # (P4)
        "e1_m": speed_mps * state[STATE["e2_rad"]] + vy,  # (P5)
        "e2_rad": r - yaw_rate_ref_radps,  # (P6)
    }
    return ca.vertcat(*(derivative[name] for name in STATE_NAMES))


def outputs(state: Symbolic) -> Symbolic:
    """The reference design's outputs ``Y`` (:data:`OUTPUT_NAMES`) of a state, a 3x1 expression."""
    return ca.vertcat(*(state[STATE[name]] for name in OUTPUT_NAMES))


def _signature() -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    return (ca.SX.sym("state", len(STATE_NAMES)), ca.SX.sym("inputs", len(INPUT_NAMES)),
            ca.SX.sym("speed_mps"), ca.SX.sym("yaw_rate_ref_radps"))


_ARGUMENT_NAMES = ["state", "inputs", "speed_mps", "yaw_rate_ref_radps"]


def continuous_function(params: PathErrorParams) -> ca.Function:
    """``f(state, inputs, speed_mps, yaw_rate_ref_radps) -> state_dot``, (P1)-(P6)."""
    state, inputs, speed, yaw_rate_ref = _signature()
    return ca.Function("path_error_bicycle", [state, inputs, speed, yaw_rate_ref],
                       [continuous_dynamics(state, inputs, speed, yaw_rate_ref, params)],
                       _ARGUMENT_NAMES, ["state_dot"])


def continuous_matrices(params: PathErrorParams,
                        speed_mps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, E)`` of ``x' = A x + B u + E psi_D'`` at ``speed_mps`` (rows and columns in
    :data:`STATE_NAMES` / :data:`INPUT_NAMES` order): the Jacobians of (P1)-(P6)."""
    state, inputs, speed, yaw_rate_ref = _signature()
    derivative = continuous_dynamics(state, inputs, speed, yaw_rate_ref, params)
    jacobians = ca.Function("path_error_matrices", [speed],
                            [ca.jacobian(derivative, state), ca.jacobian(derivative, inputs),
                             ca.jacobian(derivative, yaw_rate_ref)])
    a, b, e = jacobians(speed_mps)
    return np.asarray(a, dtype=float), np.asarray(b, dtype=float), np.asarray(e, dtype=float)


def rk4_substeps(params: PathErrorParams, dt_s: float, max_speed_mps: float = 60.0) -> int:
    """RK4 steps per ``dt_s`` so that ``h |lambda| <= SUBSTEP_LIMIT`` for every eigenvalue
    of ``A(v0)`` from ``v_low`` (nothing stiffer is ever evaluated) to ``max_speed_mps``."""
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise ConfigError(f"dt_s = {dt_s!r}: expected a positive step")
    speeds = np.linspace(params.low_speed_mps, max(max_speed_mps, params.low_speed_mps), 50)
    largest = max(float(np.max(np.abs(np.linalg.eigvals(continuous_matrices(params, v)[0]))))
                  for v in speeds)
    return max(1, math.ceil(dt_s * largest / SUBSTEP_LIMIT))


def discrete_function(params: PathErrorParams, dt_s: float,
                      substeps: int | None = None) -> ca.Function:
    """``F(state, inputs, speed_mps, yaw_rate_ref_radps) -> next_state`` over ``dt_s``,
    inputs and desired yaw rate held (default substeps: :func:`rk4_substeps`)."""
    if substeps is None:
        substeps = rk4_substeps(params, dt_s)
    if not (isinstance(substeps, int) and substeps >= 1):
        raise ConfigError(f"substeps = {substeps!r}: expected an integer >= 1")
    state, inputs, speed, yaw_rate_ref = _signature()
    h = dt_s / substeps

    def f(x: ca.SX) -> ca.SX:
        return continuous_dynamics(x, inputs, speed, yaw_rate_ref, params)

    x = state
    for _ in range(substeps):
        x = rk4_step(f, x, h)
    return ca.Function("path_error_bicycle_rk4", [state, inputs, speed, yaw_rate_ref], [x],
                       _ARGUMENT_NAMES, ["next_state"])
