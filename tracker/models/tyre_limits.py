"""The tyres' friction limit as a soft constraint of the dynamic NMPC: one ellipse per axle.

Why: the dynamic bicycle's linear tyres (:mod:`tracker.models.dynamic_bicycle`, (D3)) give any
force the plan asks for, and the acceleration input ``vx' = a`` costs no grip at all. On a
wet road the plan then asks more of the rear axle than it has: the rear-driven sedan,
accelerating at its bound into the lane change, spins its rear wheels and turns round, even
with the belief knowing the friction (docs/defaults.md). The soft slip-angle
limits (lateral only) cannot see it.

The constraint (the friction circle of each axle, e.g. Rajamani 2012, sec. 13.2 "tire
force limits"; the per-axle form used for MPC by Beal and Gerdes, "Model predictive control
for vehicle stabilization at the limits of handling", IEEE TCST 21(4), 2013) at stage ``k``
from the state ``x_k`` and the planned acceleration ``a_k``::

    F_x = m a + 1/2 rho C_d A vx^2 + C_rr m g            total longitudinal tyre force  (T1)
    F_zf = m (g l_r - a h) / L,  F_zr = m (g l_f + a h) / L   (longitudinal load transfer) (T2)
    F_xf, F_xr: F_x > 0 on the driven axle(s) (split equally when all four are driven);
                F_x < 0 over both axles in proportion to their loads (ideal braking)     (T3)
    F_yf = C_f alpha_f,  F_yr = C_r alpha_r               (D1)-(D3) at the actuator's angle
    u_i = (F_xi^2 + F_yi^2) / (mu F_zi)^2 <= usage_max^2                                 (T4)

soft, like the slip limits (:class:`tracker.mpc.nmpc.NmpcModel`, a quadratic exterior penalty
weighted ``weights.tyre_excess``): a car already beyond its grip never makes the NLP
infeasible. The split (T3) of ``F_x`` into a drive part ``max(F_x, 0)`` and a brake part
``min(F_x, 0)`` is blended over a few tens of newtons instead::

    drive = (F_x + sqrt(F_x^2 + e^2)) / 2,   brake = (F_x - sqrt(F_x^2 + e^2)) / 2     (T3')

(``e``: :data:`DRIVE_BLEND_N`; within ``e^2 / (4 |F_x|)`` of the exact split, 0.6 N at
1,000 N). With the exact split the penalty was continuously differentiable but its second
derivative jumped where the plan changes from braking to driving (each axle's share of
``F_x`` is another on either side); an optimum with a stage there, coasting through a
swerve on a wet road, made fatrop's Newton steps cycle across the jump (the dual
infeasibility 1e-3, 1e2, 0.7, 1e-3 ... for 33 iterations, then a failed restoration), a
fallback step for a plan whose cost had converged to eight digits. Lateral load transfer is
left out (it lowers an axle's grip through the tyres' load sensitivity); ``usage_max`` < 1
covers it.

Measured, with the cost of the constraint (it is added only when the believed friction is
below ``grip.tyre_limits_below_friction``): docs/defaults.md, the friction ellipse.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from cosim.core.exceptions import ConfigError
from cosim.core.physical_constants import AIR_DENSITY_KGPM3
from cosim.core.vehicle_params import VehicleParams
from tracker.models import dynamic_bicycle as bicycle
from tracker.models.steered_dynamic_bicycle import INPUT, STATE, STATE_NAMES, SteeredBicycleParams

Symbolic = ca.SX | ca.MX | ca.DM

DRIVE_BLEND_N = 50.0
"""``e`` of (T3'): the force over which the drive and the brake parts of ``F_x`` blend [N]
(the sedan's rolling resistance is some 190 N)."""

LIMIT_NAMES: tuple[str, ...] = ("front_friction_usage_sq", "rear_friction_usage_sq")
"""The outputs of :func:`friction_usage_function`: ``u_f`` and ``u_r`` of (T4)."""


def _drive_shares(drive: str) -> tuple[float, float]:
    """The share of the drive force on the front and the rear axle."""
    shares = {"rwd": (0.0, 1.0), "fwd": (1.0, 0.0), "awd": (0.5, 0.5)}
    if drive not in shares:
        raise ConfigError(f"model.drive = {drive!r}: expected one of {', '.join(shares)}")
    return shares[drive]


USAGE_BELIEF_NAMES: tuple[str, ...] = (
    "cog_height_m", "drag_area_m2", "rolling_resistance", "front_drive_share",
    "rear_drive_share")
"""The numbers (T1)-(T4) read besides the bicycle's and the friction, in vector order
(:func:`usage_belief_vector`, :func:`friction_usage`)."""


def usage_belief_vector(vehicle: VehicleParams) -> np.ndarray:
    """The numbers of :data:`USAGE_BELIEF_NAMES` for the belief ``vehicle``."""
    front_share, rear_share = _drive_shares(vehicle.drive)
    return np.array([vehicle.cog_height_m, vehicle.drag_area_m2, vehicle.rolling_resistance,
                     front_share, rear_share], dtype=float)


def friction_usage(state: Symbolic, inputs: Symbolic, bicycle_vector: Symbolic | np.ndarray,
                   usage_belief: Symbolic | np.ndarray, friction: Symbolic | float,
                   low_speed_mps: float) -> Symbolic:
    """``[u_f, u_r]`` of (T1)-(T4) at ``state`` with ``inputs``: the bicycle's numbers
    (:data:`tracker.models.dynamic_bicycle.PARAM_NAMES`), the others
    (:data:`USAGE_BELIEF_NAMES`) and the friction as floats or symbols; the slip angles
    guarded below ``low_speed_mps`` as the model's."""
    def b(name: str) -> Symbolic:
        return bicycle_vector[bicycle.PARAM[name]]

    def v(name: str) -> Symbolic:
        return usage_belief[USAGE_BELIEF_NAMES.index(name)]

    g = bicycle.GRAVITY_MPS2
    accel = inputs[INPUT["accel_mps2"]]
    vx = state[STATE["vx_mps"]]
    mass, height = b("mass_kg"), v("cog_height_m")
    cog_front, cog_rear = b("cog_front_m"), b("cog_rear_m")
    wheelbase = cog_front + cog_rear

    resistance = (0.5 * AIR_DENSITY_KGPM3 * v("drag_area_m2") * vx * ca.fabs(vx)
                  + v("rolling_resistance") * mass * g)
    force_x = mass * accel + resistance  # (T1)
    load_front = mass * (g * cog_rear - accel * height) / wheelbase  # (T2)
    load_rear = mass * (g * cog_front + accel * height) / wheelbase
    # (T3'): the drive and brake parts of F_x, blended over DRIVE_BLEND_N (module docstring).
    blend = ca.sqrt(force_x * force_x + DRIVE_BLEND_N**2)
    drive = 0.5 * (force_x + blend)
    brake = 0.5 * (force_x - blend)
    weight = mass * g
    force_x_front = v("front_drive_share") * drive + brake * load_front / weight  # (T3)
    force_x_rear = v("rear_drive_share") * drive + brake * load_rear / weight

    lateral = ca.vertcat(state[STATE["vy_mps"]], state[STATE["yaw_rate_radps"]])
    alpha_f, alpha_r = bicycle.slip_angles(lateral, state[STATE["road_wheel_angle_rad"]], vx,
                                           bicycle_vector, low_speed_mps)
    force_y_front = b("cornering_stiffness_front_npr") * alpha_f
    force_y_rear = b("cornering_stiffness_rear_npr") * alpha_r
    # A load cannot fall below a tenth of the static one in the formula (a plan braking
    # or accelerating beyond any road's grip must not divide by zero).
    grip_front = friction * ca.fmax(load_front, 0.1 * weight * cog_rear / wheelbase)
    grip_rear = friction * ca.fmax(load_rear, 0.1 * weight * cog_front / wheelbase)
    return ca.vertcat((force_x_front**2 + force_y_front**2) / grip_front**2,  # (T4)
                      (force_x_rear**2 + force_y_rear**2) / grip_rear**2)


def friction_usage_function(vehicle: VehicleParams, params: SteeredBicycleParams,
                            friction: float, low_speed_mps: float | None = None
                            ) -> ca.Function:
    """``h(state, inputs) -> [u_f, u_r]`` of (T1)-(T4) for the belief ``vehicle`` (mass,
    CoG height, drag, rolling resistance, driven axles) with the axle stiffnesses of
    ``params`` and the friction ``friction``; the slip angles guarded at low speed as the
    model's (default: ``params.low_speed_mps``)."""
    if not (math.isfinite(friction) and friction > 0.0):
        raise ConfigError(f"friction = {friction!r}: expected a positive number")
    guard = params.low_speed_mps if low_speed_mps is None else low_speed_mps
    state = ca.SX.sym("state", len(STATE_NAMES))
    inputs = ca.SX.sym("inputs", len(INPUT))
    usage = friction_usage(state, inputs, params.bicycle.as_vector(),
                           usage_belief_vector(vehicle), friction, guard)
    return ca.Function("tyre_friction_usage", [state, inputs], [usage],
                       ["state", "inputs"], ["usage_sq"])


def usage_bounds(usage_max: float) -> tuple[float, float]:
    """``usage_max^2`` for both axles, the bounds of (T4)."""
    if not (math.isfinite(usage_max) and 0.0 < usage_max <= 1.0):
        raise ConfigError(f"grip.usage_max = {usage_max!r}: expected a share in (0, 1]")
    return usage_max**2, usage_max**2
