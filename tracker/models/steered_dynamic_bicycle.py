"""The linear-tyre dynamic bicycle with its steering actuator, for a controller's model.

The vehicle is the dynamic bicycle of Rajamani 2012, sec. 2.3, (D1)-(D6) of
:mod:`tracker.models.dynamic_bicycle` (reused, not re-derived). Added here, for the ``dynamic-nmpc``
tracker:

* **The steering actuator as a state.** State :data:`STATE_NAMES` is the dynamic bicycle's
  ``[x_m, y_m, yaw_rad, vx_mps, vy_mps, yaw_rate_radps]`` plus ``road_wheel_angle_rad``, the
  front road-wheel angle the actuator has reached. Inputs :data:`INPUT_NAMES` are the
  tracker's command ``[accel_mps2, steer_rad]``: ``steer_rad`` is the angle *asked for*,
  held over a stage as the runner holds a command between control steps. The actuator is
  a first-order lag of time constant ``tau`` (the belief ``steer_time_constant_s``; the
  plant's actuator is the same lag, with a rate limit)::

      delta' = (delta_cmd - delta) / tau                                     (A1)
      delta(t) = delta_cmd + (delta_0 - delta_cmd) exp(-t / tau)             (A2)

  (A2) is the exact solution over a stage; ``tau = 0`` means ``delta = delta_cmd``.
  The other common choice, the steering *rate* as the input, assumes a ramp between
  samples that the runner cannot deliver (a command is one angle per control period);
  the lag is what the plant's actuator does with a held command, so the model is exact
  there and the NLP's input stays the command itself. The plant's rate limit is not
  modelled: the tracker's bound on the command's rate (``max_steer_rate_radps``) keeps
  the lag's rate below it in the lane change (at most 0.42 of 0.8 rad/s on the sedan; it
  is reached only at the limit, on Falcone's unstretched path).

* **Low speeds.** (D1)-(D2) divide by ``vx``: the slip angles use ``fmax(vx, v_low)``
  (:func:`tracker.models.dynamic_bicycle.slip_angles`), so the model stays finite and its
  eigenvalues bounded (down to -29 1/s at 4 m/s for the default sedan; -121 1/s at 1 m/s).
  The guard alone would be wrong at low speed: a tyre that barely slips forces
  ``alpha ~ 0``, so the guarded model turns at ``r = v_low delta / L`` instead of
  ``vx delta / L``. The velocities that move the pose are therefore blended with the
  kinematic bicycle's (:mod:`tracker.models.kinematic_bicycle`, (K1)-(K4), small angles; the
  blend of Kabzan et al., "Learning-based model predictive control for autonomous
  racing", RA-L 2019)::

      lambda  = clip((vx - v_low) / (v_high - v_low), 0, 1)                 (B1)
      vy_pose = lambda vy + (1 - lambda) vx tan(delta) l_r / L               (B2)
      r_pose  = lambda r  + (1 - lambda) vx tan(delta) / L                   (B3)
      x' = vx cos(yaw) - vy_pose sin(yaw),  y' = vx sin(yaw) + vy_pose cos(yaw),
      yaw' = r_pose                                                          (B4)

  ``vy`` and ``r`` themselves always follow (D4)-(D5). Above ``v_high`` the model is
  exactly (D1)-(D6); below ``v_low`` it is the kinematic bicycle.

* **Tyres that saturate** (``saturating``): the axle forces (D3') of
  :mod:`tracker.models.dynamic_bicycle`, held within the friction force of the axle's
  static load at the belief's friction; the tyres of (D3) otherwise.

Discretisation: classical RK4 on the six vehicle states with the steering angle of (A2)
at the RK4 stage times (so the actuator is integrated exactly), ``substeps`` per stage,
chosen by :func:`rk4_substeps` from the lateral eigenvalues so that ``h |lambda| <= 1.5``
(RK4 is stable up to 2.79 on the negative real axis).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from types import MappingProxyType

import casadi as ca
import numpy as np

from cosim.core.exceptions import ConfigError
from cosim.core.vehicle_equations import rk4_step_in_time
from cosim.core.vehicle_params import VehicleParams
from tracker.models import dynamic_bicycle as bicycle

VEHICLE_STATE_NAMES: tuple[str, ...] = bicycle.STATE_NAMES
"""The dynamic bicycle's states, in vector order."""

STATE_NAMES: tuple[str, ...] = VEHICLE_STATE_NAMES + ("road_wheel_angle_rad",)
"""State of the steered model, in vector order."""

INPUT_NAMES: tuple[str, ...] = ("accel_mps2", "steer_rad")
"""Inputs: longitudinal acceleration and the steering command (the road-wheel angle asked
for), in vector order."""

STATE = MappingProxyType({name: i for i, name in enumerate(STATE_NAMES)})
"""Read-only map from state name to its index in the state vector."""

INPUT = MappingProxyType({name: i for i, name in enumerate(INPUT_NAMES)})
"""Read-only map from input name to its index in the input vector."""

RK4_STEP_LIMIT = 1.5
"""Largest ``h |lambda|`` :func:`rk4_substeps` allows (RK4's real stability bound is 2.79)."""

Symbolic = ca.SX | ca.MX | ca.DM


@dataclass(frozen=True)
class SteeredBicycleParams:
    """Numbers of the steered model: the bicycle, the actuator and the low-speed blend."""

    bicycle: bicycle.DynamicBicycleParams
    steer_time_constant_s: float
    """First-order lag of the steering actuator, tau of (A1) [s]; 0 for none."""
    low_speed_mps: float = 4.0
    """v_low of (B1): below it the pose moves kinematically; the slip-angle guard [m/s]."""
    high_speed_mps: float = 6.0
    """v_high of (B1): above it the model is the dynamic bicycle alone [m/s]."""
    tyre_friction: float = 1.0
    """The road's friction ``mu`` the tyres saturate at, (D3') (read only when
    ``saturating``)."""
    saturating: bool = False
    """The tyres saturate at the friction force of their axle's load, (D3') of
    :mod:`tracker.models.dynamic_bicycle`; linear, (D3), when False. The model's shape."""

    def __post_init__(self) -> None:
        tau = self.steer_time_constant_s
        if not (math.isfinite(tau) and tau >= 0.0):
            raise ConfigError(f"steer_time_constant_s = {tau!r}: expected a finite number >= 0")
        if not (math.isfinite(self.low_speed_mps) and self.low_speed_mps > 0.0):
            raise ConfigError(f"low_speed_mps = {self.low_speed_mps!r}: expected a positive "
                              "speed")
        if not (math.isfinite(self.high_speed_mps) and self.high_speed_mps > self.low_speed_mps):
            raise ConfigError(f"high_speed_mps = {self.high_speed_mps!r}: expected more than "
                              f"low_speed_mps = {self.low_speed_mps}")
        if not (math.isfinite(self.tyre_friction) and self.tyre_friction > 0.0):
            raise ConfigError(f"tyre_friction = {self.tyre_friction!r}: expected a positive "
                              "number")

    @classmethod
    def from_vehicle(cls, vehicle: VehicleParams,
                     saturating: bool = False) -> SteeredBicycleParams:
        """The belief ``vehicle``: mass, yaw inertia, CoG position, axle cornering
        stiffnesses, the steering time constant and the friction (the tyres saturate there
        when ``saturating``)."""
        return cls(
            bicycle=bicycle.DynamicBicycleParams.from_vehicle(
                vehicle,
                vehicle.cornering_stiffness_front_npr,
                vehicle.cornering_stiffness_rear_npr,
            ),
            steer_time_constant_s=vehicle.steer_time_constant_s,
            tyre_friction=vehicle.tyre_friction,
            saturating=saturating,
        )


BELIEF_NAMES: tuple[str, ...] = bicycle.PARAM_NAMES + ("steer_time_constant_s", "tyre_friction")
"""The belief's numbers as the belief-parametric functions take them, in vector order
(:func:`belief_vector`, :func:`belief_discrete_function`)."""

BELIEF = MappingProxyType({name: i for i, name in enumerate(BELIEF_NAMES)})
"""Read-only map from belief name to its index in the belief vector."""


def belief_vector(params: SteeredBicycleParams) -> np.ndarray:
    """The numbers of ``params`` in :data:`BELIEF_NAMES` order."""
    return np.append(params.bicycle.as_vector(),
                     [float(params.steer_time_constant_s), float(params.tyre_friction)])


@dataclass(frozen=True)
class ModelNumbers:
    """The numbers the model's equations read: floats (the belief baked into a function)
    or CasADi symbols (the belief an input of the function, so that one function, and one
    compiled library, serves every belief of the same *shape*).

    The shape is what changes the equations themselves rather than their numbers: whether
    the actuator lags (``tau > 0``), whether the tyres saturate, and the low-speed blend's
    speeds, which are the model's design, not the car's."""

    bicycle_vector: Symbolic | np.ndarray
    """The dynamic bicycle's parameters, :data:`tracker.models.dynamic_bicycle.PARAM_NAMES`."""
    wheelbase_m: Symbolic | float
    cog_rear_m: Symbolic | float
    steer_time_constant_s: Symbolic | float
    lagged: bool
    """``tau > 0``: the actuator is the lag (A1)-(A2); otherwise the command itself."""
    low_speed_mps: float
    high_speed_mps: float
    friction: Symbolic | float | None = None
    """The friction the tyres saturate at, (D3'); None: linear tyres, (D3)."""

    @classmethod
    def of(cls, params: SteeredBicycleParams) -> ModelNumbers:
        """The numbers of ``params`` as floats."""
        return cls(params.bicycle.as_vector(), params.bicycle.wheelbase_m,
                   params.bicycle.cog_rear_m, params.steer_time_constant_s,
                   params.steer_time_constant_s > 0.0, params.low_speed_mps,
                   params.high_speed_mps,
                   params.tyre_friction if params.saturating else None)

    @classmethod
    def symbolic(cls, belief: Symbolic, params: SteeredBicycleParams) -> ModelNumbers:
        """The numbers read from the belief vector ``belief`` (:data:`BELIEF_NAMES`),
        with the shape of ``params``."""
        vector = belief[:len(bicycle.PARAM_NAMES)]
        front = belief[BELIEF["cog_front_m"]]
        rear = belief[BELIEF["cog_rear_m"]]
        return cls(vector, front + rear, rear, belief[BELIEF["steer_time_constant_s"]],
                   params.steer_time_constant_s > 0.0, params.low_speed_mps,
                   params.high_speed_mps,
                   belief[BELIEF["tyre_friction"]] if params.saturating else None)


def road_wheel_angle(angle0_rad: Symbolic, command_rad: Symbolic, t_s: Symbolic | float,
                     steer_time_constant_s: Symbolic | float,
                     lagged: bool | None = None) -> Symbolic:
    """The actuator's angle ``t_s`` after ``angle0_rad`` with ``command_rad`` held, (A2).

    ``lagged`` says whether the actuator lags at all (default: ``tau > 0``, which a symbolic
    ``tau`` cannot answer)."""
    if lagged is None:
        lagged = steer_time_constant_s > 0.0
    if not lagged:
        return command_rad
    return command_rad + (angle0_rad - command_rad) * ca.exp(-t_s / steer_time_constant_s)


def vehicle_dynamics(vehicle_state: Symbolic, accel_mps2: Symbolic, steer_rad: Symbolic,
                     params: SteeredBicycleParams | ModelNumbers) -> Symbolic:
    """Time derivative of the six vehicle states at road-wheel angle ``steer_rad``:
    (D1)-(D6) with the guarded slip angles (and (D3') when the numbers hold a friction), the
    pose moved by (B1)-(B4)."""
    numbers = params if isinstance(params, ModelNumbers) else ModelNumbers.of(params)
    by_name = {"accel_mps2": accel_mps2, "steer_rad": steer_rad}
    inputs = ca.vertcat(*(by_name[name] for name in bicycle.INPUT_NAMES))
    dynamic = bicycle.continuous_dynamics(vehicle_state, inputs, numbers.bicycle_vector,
                                          numbers.low_speed_mps, numbers.friction)
    yaw = vehicle_state[bicycle.STATE["yaw_rad"]]
    vx = vehicle_state[bicycle.STATE["vx_mps"]]
    vy = vehicle_state[bicycle.STATE["vy_mps"]]
    r = vehicle_state[bicycle.STATE["yaw_rate_radps"]]
    wheelbase = numbers.wheelbase_m
    weight = ca.fmin(ca.fmax((vx - numbers.low_speed_mps)
                             / (numbers.high_speed_mps - numbers.low_speed_mps), 0.0),
                     1.0)  # (B1)
    curvature = ca.tan(steer_rad) / wheelbase
    vy_pose = weight * vy + (1.0 - weight) * vx * curvature * numbers.cog_rear_m  # (B2)
    r_pose = weight * r + (1.0 - weight) * vx * curvature  # (B3)
    derivative = {
        "x_m": vx * ca.cos(yaw) - vy_pose * ca.sin(yaw),  # (B4)
        "y_m": vx * ca.sin(yaw) + vy_pose * ca.cos(yaw),
        "yaw_rad": r_pose,
        "vx_mps": dynamic[bicycle.STATE["vx_mps"]],
        "vy_mps": dynamic[bicycle.STATE["vy_mps"]],
        "yaw_rate_radps": dynamic[bicycle.STATE["yaw_rate_radps"]],
    }
    return ca.vertcat(*(derivative[name] for name in VEHICLE_STATE_NAMES))


def continuous_dynamics(state: Symbolic, inputs: Symbolic,
                        params: SteeredBicycleParams) -> Symbolic:
    """Time derivative of the full state, (A1) and (B1)-(B4), as a 7x1 expression.

    With ``tau = 0`` the actuator is instantaneous and ``road_wheel_angle_rad`` has no
    dynamics of its own (its derivative is reported as 0; the vehicle sees the command).
    """
    angle = state[STATE["road_wheel_angle_rad"]]
    command = inputs[INPUT["steer_rad"]]
    tau = params.steer_time_constant_s
    steer = angle if tau > 0.0 else command
    vehicle = vehicle_dynamics(_vehicle_part(state), inputs[INPUT["accel_mps2"]], steer, params)
    angle_rate = (command - angle) / tau if tau > 0.0 else 0.0 * angle
    return ca.vertcat(vehicle, angle_rate)


def _vehicle_part(state: Symbolic) -> Symbolic:
    return ca.vertcat(*(state[STATE[name]] for name in VEHICLE_STATE_NAMES))


@functools.lru_cache(maxsize=8)
def _dynamics_function(parameter_count: int, low_speed_mps: float,
                       high_speed_mps: float, saturating: bool) -> ca.Function:
    """:func:`vehicle_dynamics` as a CasADi function of the vehicle state, the inputs and
    the numbers that may be symbols (the bicycle's vector, the wheelbase, the CoG to rear
    axle and, for ``saturating`` tyres, the friction), for the low-speed blend's speeds
    (the model's design, constants): an RK4 step
    calls it at each of its stages, which CasADi expands into the same operations as
    writing the equations out there, and the equations are written in Python once instead
    of at each of the 24 stages of a model's functions (some 25 ms of a process's set-up)."""
    vehicle_state = ca.SX.sym("vehicle_state", len(VEHICLE_STATE_NAMES))
    accel, steer = ca.SX.sym("accel_mps2"), ca.SX.sym("steer_rad")
    vector = ca.SX.sym("bicycle", parameter_count)
    wheelbase, cog_rear = ca.SX.sym("wheelbase_m"), ca.SX.sym("cog_rear_m")
    friction = ca.SX.sym("tyre_friction") if saturating else None
    numbers = ModelNumbers(vector, wheelbase, cog_rear, 0.0, False, low_speed_mps,
                           high_speed_mps, friction)
    inputs = [vehicle_state, accel, steer, vector, wheelbase, cog_rear]
    return ca.Function("vehicle_dynamics", inputs + ([friction] if saturating else []),
                       [vehicle_dynamics(vehicle_state, accel, steer, numbers)])


def _advance(state: Symbolic, inputs: Symbolic, duration_s: Symbolic | float, substeps: int,
             numbers: ModelNumbers) -> Symbolic:
    """``substeps`` RK4 steps over ``duration_s`` with the inputs held; the actuator by (A2)."""
    accel = inputs[INPUT["accel_mps2"]]
    command = inputs[INPUT["steer_rad"]]
    angle0 = state[STATE["road_wheel_angle_rad"]]
    tau, lagged = numbers.steer_time_constant_s, numbers.lagged
    h = duration_s / substeps

    saturating = numbers.friction is not None
    dynamics = _dynamics_function(numbers.bicycle_vector.shape[0], numbers.low_speed_mps,
                                  numbers.high_speed_mps, saturating)
    fixed = (numbers.bicycle_vector, numbers.wheelbase_m, numbers.cog_rear_m,
             *((numbers.friction,) if saturating else ()))

    def f(vehicle_state: Symbolic, t_s: Symbolic | float) -> Symbolic:
        steer = road_wheel_angle(angle0, command, t_s, tau, lagged)
        return dynamics(vehicle_state, accel, steer, *fixed)

    vehicle = _vehicle_part(state)
    for i in range(substeps):
        vehicle = rk4_step_in_time(f, vehicle, i * h, h)
    angle = road_wheel_angle(angle0, command, duration_s, tau, lagged)
    return ca.vertcat(vehicle, angle)


def rk4_substeps(params: SteeredBicycleParams, dt_s: float,
                 max_speed_mps: float = 60.0) -> int:
    """RK4 steps per ``dt_s`` so that ``h |lambda| <= RK4_STEP_LIMIT`` for every lateral
    eigenvalue from ``v_low`` (the guard: nothing stiffer is ever evaluated) to
    ``max_speed_mps``."""
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise ConfigError(f"dt_s = {dt_s!r}: expected a positive step")
    speeds = np.linspace(params.low_speed_mps, max(max_speed_mps, params.high_speed_mps), 50)
    largest = max(
        float(np.max(np.abs(np.linalg.eigvals(params.bicycle.lateral_state_space(v)[0]))))
        for v in speeds
    )
    return max(1, math.ceil(dt_s * largest / RK4_STEP_LIMIT))


def slip_angles_of(state: Symbolic, numbers: ModelNumbers) -> Symbolic:
    """The axle slip angles (D1)-(D2) ``[front_slip_rad, rear_slip_rad]`` of ``state`` at
    the road-wheel angle the actuator has reached, guarded at low speed."""
    by_name = {"vy_mps": state[STATE["vy_mps"]], "yaw_rate_radps": state[STATE["yaw_rate_radps"]]}
    lateral = ca.vertcat(*(by_name[name] for name in bicycle.LATERAL_STATE_NAMES))
    alpha_f, alpha_r = bicycle.slip_angles(lateral, state[STATE["road_wheel_angle_rad"]],
                                           state[STATE["vx_mps"]], numbers.bicycle_vector,
                                           numbers.low_speed_mps)
    return ca.vertcat(alpha_f, alpha_r)


def slip_angle_function(params: SteeredBicycleParams) -> ca.Function:
    """``h(state) -> [front_slip_rad, rear_slip_rad]``: the axle slip angles (D1)-(D2) at
    the road-wheel angle the actuator has reached, guarded at low speed."""
    state = ca.SX.sym("state", len(STATE_NAMES))
    return ca.Function("steered_dynamic_bicycle_slip", [state],
                       [slip_angles_of(state, ModelNumbers.of(params))],
                       ["state"], ["slip_rad"])


def linear_range_of(bicycle_vector: Symbolic | np.ndarray,
                    friction: Symbolic | float) -> tuple[Symbolic, Symbolic]:
    """:func:`linear_range_slip_rad` from the bicycle's parameter vector and the friction,
    floats or symbols."""
    def p(name: str) -> Symbolic:
        return bicycle_vector[bicycle.PARAM[name]]

    weight_n = p("mass_kg") * bicycle.GRAVITY_MPS2
    wheelbase = p("cog_front_m") + p("cog_rear_m")
    front = friction * weight_n * p("cog_rear_m") / (wheelbase
                                                     * p("cornering_stiffness_front_npr"))
    rear = friction * weight_n * p("cog_front_m") / (wheelbase
                                                     * p("cornering_stiffness_rear_npr"))
    return front, rear


def linear_range_slip_rad(params: SteeredBicycleParams, friction: float) -> tuple[float, float]:
    """Front and rear slip angles at which the linear tyres (D3) reach the friction limit
    ``mu F_z`` of their axle's static load, ``mu m g l_r / (L C_f)`` and
    ``mu m g l_f / (L C_r)`` [rad]: beyond them the model's forces do not exist."""
    if not (math.isfinite(friction) and friction > 0.0):
        raise ConfigError(f"friction = {friction!r}: expected a positive number")
    front, rear = linear_range_of(params.bicycle.as_vector(), friction)
    return float(front), float(rear)


def continuous_function(params: SteeredBicycleParams) -> ca.Function:
    """``f(state, inputs) -> state_dot`` of (A1), (B1)-(B4)."""
    state = ca.SX.sym("state", len(STATE_NAMES))
    inputs = ca.SX.sym("inputs", len(INPUT_NAMES))
    return ca.Function("steered_dynamic_bicycle", [state, inputs],
                       [continuous_dynamics(state, inputs, params)],
                       ["state", "inputs"], ["state_dot"])


def discrete_function(params: SteeredBicycleParams, dt_s: float,
                      substeps: int | None = None) -> ca.Function:
    """``F(state, inputs) -> next_state`` over ``dt_s`` (default substeps:
    :func:`rk4_substeps`)."""
    substeps = _substeps(params, dt_s, substeps)
    state = ca.SX.sym("state", len(STATE_NAMES))
    inputs = ca.SX.sym("inputs", len(INPUT_NAMES))
    return ca.Function("steered_dynamic_bicycle_rk4", [state, inputs],
                       [_advance(state, inputs, dt_s, substeps, ModelNumbers.of(params))],
                       ["state", "inputs"], ["next_state"])


def _substeps(params: SteeredBicycleParams, dt_s: float, substeps: int | None) -> int:
    """``substeps``, checked, or :func:`rk4_substeps` when None."""
    if substeps is None:
        substeps = rk4_substeps(params, dt_s)
    if not (isinstance(substeps, int) and substeps >= 1):
        raise ConfigError(f"substeps = {substeps!r}: expected an integer >= 1")
    return substeps


def belief_discrete_function(params: SteeredBicycleParams, dt_s: float,
                             substeps: int | None = None) -> ca.Function:
    """``F(state, inputs, belief) -> next_state``: :func:`discrete_function` with the belief
    an input (:data:`BELIEF_NAMES`, :func:`belief_vector`) rather than numbers in the code;
    ``params`` gives the shape (:class:`ModelNumbers`) and the default substeps. At
    ``belief = belief_vector(params)`` it computes what ``discrete_function(params, dt_s)``
    does, operation for operation."""
    substeps = _substeps(params, dt_s, substeps)
    state = ca.SX.sym("state", len(STATE_NAMES))
    inputs = ca.SX.sym("inputs", len(INPUT_NAMES))
    belief = ca.SX.sym("belief", len(BELIEF_NAMES))
    numbers = ModelNumbers.symbolic(belief, params)
    return ca.Function("steered_dynamic_bicycle_rk4_belief", [state, inputs, belief],
                       [_advance(state, inputs, dt_s, substeps, numbers)],
                       ["state", "inputs", "belief"], ["next_state"])


def predict_function(params: SteeredBicycleParams, substeps: int = 4) -> ca.Function:
    """``P(state, inputs, duration_s) -> predicted_state`` after a variable duration
    (``substeps`` RK4 steps; meant for durations up to a few control periods).
    ``duration_s = 0`` returns the state unchanged (unless ``tau = 0``, when the road-wheel
    angle is the command at once)."""
    if not (isinstance(substeps, int) and substeps >= 1):
        raise ConfigError(f"substeps = {substeps!r}: expected an integer >= 1")
    state = ca.SX.sym("state", len(STATE_NAMES))
    inputs = ca.SX.sym("inputs", len(INPUT_NAMES))
    duration = ca.SX.sym("duration_s")
    return ca.Function("steered_dynamic_bicycle_predict", [state, inputs, duration],
                       [_advance(state, inputs, duration, substeps, ModelNumbers.of(params))],
                       ["state", "inputs", "duration_s"], ["predicted_state"])
