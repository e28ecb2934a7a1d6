"""The filters' process model, built symbolically with CasADi (the states:
   :mod:`estimation.state`).


Process model: the dynamic bicycle (Rajamani, "Vehicle Dynamics and
Control", 2nd ed., section 2.3; the equations of :mod:`tracker.models.dynamic_bicycle`, written
again here so that the filter can guard the slip angles at low speed and add what follows),
with the measured steering angle as its input through the state ``steer_rad``, a body roll
mode, and planar rigid-body kinematics::

    vy_a = vy + h p                          (lateral velocity at the roll axis)  (R1)
    alpha_f = delta - (vy_a + l_f r) / v_s, alpha_r = -(vy_a - l_r r) / v_s      (D1, D2)
    F_yf = C_f alpha_f,                     F_yr = C_r alpha_r                   (D3)
    F_yi = mu F_zi tanh(C_i alpha_i / (mu F_zi)),  i = f, r                      (D3')
    a_t = (F_yf + F_yr) / m + d             (lateral acceleration from the tyres)
    p' = -omega^2 (phi - G a_t) - 2 zeta omega p + w_p,   phi' = p               (R2)
    vy' = a_t - r vx - h p' + w_vy                                               (D4)
    r'  = (l_f F_yf - l_r F_yr) / I_z + w_r                                      (D5)
    x' = vx cos(yaw) - vy sin(yaw) + w_x,   y' = vx sin(yaw) + vy cos(yaw) + w_y (D6)
    yaw' = r + w_yaw,   vx' = ax + r vy,    ax' = w_j,
    delta' = delta_r + w_delta,   delta_r' = w_dr
    d' = -d / tau_d + w_d,   b_g' = w_bg,   b_x' = w_bx,   b_y' = w_by,   k' = w_k,   k_t' = w_t

The roll mode (R1)-(R2) is a second-order system driven by the tyres' lateral
acceleration with the steady roll gradient ``G``, natural frequency ``omega`` and damping
ratio ``zeta`` (Gillespie, "Fundamentals of Vehicle Dynamics", ch. 8, roll gradient;
:class:`estimation.bicycle.RollParams`); the CoG sits ``h`` (the belief's ``cog_height_m``)
above the roll axis, so when the body rolls it sways sideways relative to the axles: the
tyres see the axles' lateral velocity ``vy + h p``, an IMU and a GNSS antenna at the CoG see
the sway. On
the MuJoCo sedan the sway is 2.5 cm at 0.5 g and the CoG's lateral acceleration differs
from the tyres' by up to 1 m/s^2 in a lane change: without (R1)-(R2) the tyre model's
error in lateral acceleration is 0.13 m/s^2 RMS, with them 0.05 m/s^2.

The axles' lateral forces (D1)-(D3'), with the load transfer between the axles (D3'') and
the tyres' relaxation (D3'''), and the bicycle's numbers (:class:`BicycleParams`,
:class:`RollParams`) are :mod:`estimation.bicycle`'s.

``d`` is ``lateral_accel_residual_mps2``, a first-order Gauss-Markov process: the tyre model
is trusted on average, but the IMU's lateral acceleration can pull the force it predicts to
what the car really does, so the side slip keeps being integrated correctly where the model
is wrong. ``b_g``, ``b_x`` and ``b_y`` are the biases of the gyro and of the longitudinal
and lateral accelerometers (random walks, as the sensors' biases are), ``k`` the
rolling-radius scale and every ``w`` white noise of the configured power spectral density
(``estimation.config``; the values were set from the MuJoCo sedan's truth: e.g. the
yaw-acceleration error of the model has a PSD of 1e-5 to 4e-4 rad^2/s^3, the residual ``d``
0.05-0.15 m/s^2 RMS with a correlation time of 0.3-0.5 s). Three of the PSDs grow with the
tyre forces the model predicts, because the model's error does: the residual's with ``(eps
a_y)^2`` (a tyre's force known to a fraction ``eps`` of itself), the roll acceleration's
with the roll acceleration the force commands, and the heading's with the bicycle's yaw
acceleration squared (a yaw response that lags the model's by an uncertain few milliseconds,
tyre relaxation and compliance, is off by ``tau r'`` while the yaw rate changes, too briefly
for the gyro to resolve): with constant PSDs the filter was under-confident on the straights
and over-confident in the swerves of the same lane change (:class:`ProcessNoise`). Without
``b_x`` the accelerometer's bias (0.02 m/s^2) makes the speed from the IMU drift against the
wheel speeds, and the filter explains the conflict with a drifting rolling radius: the speed
was off by 0.11 m/s (0.5 %) on the lane change with 0.5 m GNSS. Without ``b_y`` the lateral
accelerometer's bias (0.02 m/s^2 turn-on spread) is read as a yaw rate ``b_y / vx`` (about
1e-3 rad/s at 20 m/s, since ``a_y = vy' + r vx``) and the gyro's bias estimate takes the
opposite: on the lane change with 0.5 m GNSS it stayed up to 1.2e-3 rad/s (2.7 sigma) off
for the whole run, the heading drifted on every straight and its NEES share was 2.4 where 1
is expected; the constant process noises had been raised to hide it.

The road-wheel angle has its rate as a state (an integrated random walk, the
constant-velocity model of Bar-Shalom, Li, Kirubarajan, "Estimation with Applications to
Tracking and Navigation", Wiley 2001, section 6.2.2): as a plain random walk, the
estimate lagged every steering ramp by a few samples, so the steering sensor's innovations
were as large as the ramp's steps, and a process noise large enough for the gnss suite's
busier steering was four times too large for the rtk suite's (NIS per dof 0.25 to 3).

``v_s`` is the forward speed with a floor at low speed
(:func:`estimation.bicycle.slip_speed`: equal to ``vx`` above ``LOW_SPEED_MPS``, never below
half of it), where the slip angles of (D1)-(D2) are undefined; below that speed the tyre model
quickly pulls the car onto the kinematic bicycle.

Discretisation over a sub-step ``dt``: the mean by one classical Runge-Kutta 4 step, its
Jacobian ``F`` by CasADi's automatic differentiation of that step, and the process noise by
the exact integral of the system linearised at the start of the sub-step (Van Loan 1978;
``dQ/dt = A Q + Q A' + W``, ``Q(0) = 0``) written as its power series
``Q(dt) = sum_k dt^(k+1)/(k+1)! L^k(W)`` with ``L(X) = A X + X A'``. The series converges
like ``(2 |A| dt)^k / k!``; the largest entries of ``A`` are the roll mode's ``omega^2``
(about 90 1/s^2) and the tyre terms at the floor speed (about 45 1/s), so
:data:`NOISE_SERIES_TERMS` terms are exact to rounding for ``dt <= MAX_STEP_S``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from cosim.core.built_once import built_once
from cosim.core.compiled_function import external_function
from cosim.core.dense_function import DenseFunction
from cosim.core.symbolic_record import symbolic_twin
from cosim.core.vehicle_equations import rk4_step
from estimation.bicycle import (
    BicycleParams,
    axle_forces,
    cog_lateral_accel,
    roll_accel,
    world_velocity,
    yaw_moment,
)
from estimation.state import (
    ANGLE_STATES,
    STATE_NAMES,
    named_states,
    stacked_states,
    state_index,
    wrap_angle_symbolic,
)
from estimation.steering_model import (
    COMMAND_INPUTS,
    SteeringBelief,
    command_input,
    gyro_deflection,
    gyro_deflection_rate,
    steering_derivatives,
)

NOISE_SERIES_TERMS = 20
"""Terms of the power series of the discrete process noise (see the module docstring)."""

MIN_RESIDUAL_TIME_CONSTANT_S = 0.05
"""Smallest time constant of the lateral residual the noise series is exact for."""

MAX_STEP_S = 0.02
"""Longest sub-step the noise series is exact for."""



@dataclass(frozen=True)
class ProcessNoise:
    """Continuous-time white-noise power spectral densities driving the states."""

    position_psd_m2ps: float
    yaw_psd_rad2ps: float
    lateral_accel_psd_m2ps3: float
    yaw_accel_psd_rad2ps3: float
    jerk_psd_m2ps5: float
    steer_psd_rad2ps: float
    steer_rate_psd_rad2ps3: float
    roll_accel_psd_rad2ps3: float
    lateral_residual_psd_m2ps5: float
    gyro_bias_psd_rad2ps3: float
    accel_bias_psd_m2ps5: float
    rolling_radius_scale_psd_1ps: float
    wheel_track_scale_psd_1ps: float = 0.0
    lateral_residual_relative_psd_1ps: float = 0.0
    """The residual's PSD per squared lateral tyre acceleration: the residual is driven by
    ``lateral_residual_psd_m2ps5 + lateral_residual_relative_psd_1ps * a_y^2`` with ``a_y``
    the tyres' force per mass (the tyre model's error grows with the force it predicts)."""
    yaw_transient_psd_s3: float = 0.0
    """The heading's PSD per squared yaw acceleration of the model: ``yaw_psd_rad2ps +
    yaw_transient_psd_s3 * r'^2``. A yaw response that lags the bicycle's by an uncertain
    time ``tau`` (tyre relaxation, steering and suspension compliance) is off by
    ``tau r'`` while the yaw rate changes, too briefly for the gyro's noise to resolve."""
    yaw_moment_relative_psd_s: float = 0.0
    """The yaw acceleration's PSD per squared yaw acceleration of each axle's moment:
    ``yaw_accel_psd_rad2ps3 + yaw_moment_relative_psd_s * ((l_f F_f)^2 + (l_r F_r)^2) / I_z^2``.
    The tyre model's balance between the axles (their effective cornering stiffnesses,
    which lateral load transfer lowers unequally) sets the side slip of a turn; its error
    grows with the axles' forces, does not show in the total lateral force the IMU
    measures, and becomes a heading error once the positions pin the course. The yaw
    moment's two large opposing parts are each known to a fraction only."""
    yaw_moment_load_transfer_psd_s5pm2: float = 0.0
    """The yaw acceleration's PSD per squared product of the longitudinal acceleration and
    each axle's yaw acceleration: ``yaw_moment_load_transfer_psd_s5pm2 a_x^2 ((l_f F_f)^2 +
    (l_r F_r)^2) / I_z^2``, beside :attr:`yaw_moment_relative_psd_s`'s term. Braking or
    driving moves load between the axles ((D3'') of :mod:`estimation.bicycle`) and takes
    part of the braked or driven tyres' grip: the axles' balance shifts by an amount the
    model knows to a fraction, an error that grows with ``a_x`` and with the forces it
    shifts, nil on a straight and in a turn at constant speed."""
    roll_accel_relative_psd_s: float = 0.0
    """The roll acceleration's PSD per squared roll acceleration the tyres' force commands,
    ``roll_accel_psd_rad2ps3 + roll_accel_relative_psd_s * (omega^2 G a_y)^2`` (the roll
    mode's steady gain and dynamics are known to a fraction)."""
    steer_rate_relative_psd_s: float = 0.0
    """The steering angle's PSD per squared steering rate: ``steer_psd_rad2ps +
    steer_rate_relative_psd_s * delta_r^2``. An actuator the filter follows from its commands
    (:mod:`estimation.steering_model`) but whose timing it knows only to some ``dt`` (the
    plant's own steps, its servo) is off by ``delta_r dt`` while it moves; the lag pulls an
    error back within ``tau``, so a PSD ``2 (delta_r dt)^2 / tau`` holds that error's
    variance: ``2 dt^2 / tau`` per squared rate. Only once told the commands
    (:func:`estimation.belief_models.told_process_noise`)."""
    jerk_relative_psd_1ps: float = 0.0
    """The longitudinal jerk's PSD per squared longitudinal acceleration:
    ``jerk_psd_m2ps5 + jerk_relative_psd_1ps * a_x^2``. The drive and brake forces change
    with the force asked of them (launch, braking) and rest when the car cruises."""

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} = {value!r}: expected a finite number >= 0")

    def diagonal(self) -> np.ndarray:
        """The PSD matrix W (diagonal), one entry per state of :data:`STATE_NAMES`."""
        return np.diag(self.psd_entries())

    def psd_entries(self) -> list[Any]:
        """W's diagonal as a list in :data:`STATE_NAMES` order (numbers, or the symbols of
        a :func:`cosim.core.symbolic_record.symbolic_twin`)."""
        psd = {
            "x_m": self.position_psd_m2ps,
            "y_m": self.position_psd_m2ps,
            "yaw_rad": self.yaw_psd_rad2ps,
            "vx_mps": 0.0,
            "vy_mps": self.lateral_accel_psd_m2ps3,
            "yaw_rate_radps": self.yaw_accel_psd_rad2ps3,
            "ax_mps2": self.jerk_psd_m2ps5,
            "steer_rad": self.steer_psd_rad2ps,
            "steer_rate_radps": self.steer_rate_psd_rad2ps3,
            "roll_rad": 0.0,
            "roll_rate_radps": self.roll_accel_psd_rad2ps3,
            "lateral_accel_residual_mps2": self.lateral_residual_psd_m2ps5,
            "gyro_bias_radps": self.gyro_bias_psd_rad2ps3,
            "ax_bias_mps2": self.accel_bias_psd_m2ps5,
            "ay_bias_mps2": self.accel_bias_psd_m2ps5,
            "rolling_radius_scale": self.rolling_radius_scale_psd_1ps,
            "wheel_track_scale": self.wheel_track_scale_psd_1ps,
        }
        return [psd[name] for name in STATE_NAMES]


@dataclass(frozen=True)
class _Belief:
    """Every number of a process model, as one record (the model's ``belief`` input)."""

    noise: ProcessNoise
    bicycle: BicycleParams
    residual_time_constant_s: float
    steering: SteeringBelief


@dataclass(frozen=True)
class _ProcessFunctions:
    """The CasADi functions of a process model (immutable: every model with the same
    numbers shares them) and the numbers of their ``belief`` input."""

    belief_names: tuple[str, ...]
    belief_values: np.ndarray
    derivative: ca.Function
    step: ca.Function
    mean_step: ca.Function
    noise: ca.Function
    psd: ca.Function
    mapped_mean_step: ca.Function | None
    cornering_drag: ca.Function
    transition_sparsity: ca.Sparsity
    """The entries of ``step``'s ``F`` that are not structurally zero (``step`` gives it
    dense)."""

    @functools.cached_property
    def covariance_step(self) -> ca.Function:
        """:func:`_covariance_step` of these functions, built on first use (kept with them:
        a covariance step kept apart could outlive the sub-step it calls, and a library
        generated with a newer one would then hold the sub-step twice)."""
        return _covariance_step(self)

    def named(self, name: str) -> ca.Function:
        """The function of CasADi name ``name`` (``bicycle_step`` ...)."""
        for function in (self.derivative, self.step, self.mean_step, self.noise, self.psd,
                         self.mapped_mean_step, self.cornering_drag):
            if function is not None and function.name() == name:
                return function
        raise KeyError(name)


COVARIANCE_STEP = "bicycle_covariance_step"
"""The CasADi name of :func:`_covariance_step`."""

_COMPILED = ("bicycle_step", "bicycle_cornering_drag", COVARIANCE_STEP)
"""The functions the EKF compiles (:meth:`ProcessModel.compiled_functions`)."""
_SIGMA_POINT_COMPILED = ("bicycle_noise", "bicycle_mean_steps", "bicycle_cornering_drag")
"""The functions the UKF compiles (:meth:`ProcessModel.sigma_point_functions`)."""


@built_once
def _process_functions(numbers: _Belief, sigma_point_count: int) -> _ProcessFunctions:
    """The functions of :class:`ProcessModel` for ``numbers``, built once per process
    (some 40 ms of symbolic work that every run's filter would otherwise repeat).

    Every number of the belief is an input of the functions (``belief``), set by the
    caller: one function, and one compiled library, for every belief."""
    record = symbolic_twin(numbers)
    twin, belief = record.twin, record.vector
    n = len(STATE_NAMES)
    x = ca.SX.sym("x", n)
    u = ca.SX.sym("u", len(COMMAND_INPUTS))
    dt = ca.SX.sym("dt_s")

    # The equations written once, as a function that each RK4 stage and the Jacobian call
    # (CasADi expands a call into the same operations: the same numbers), instead of
    # written out again at each of the five (some 15 ms of a process's set-up).
    equations = ca.Function("bicycle_equations", [x, u, belief], [_derivative(
        x, u, twin.bicycle, twin.residual_time_constant_s, twin.steering)])

    def derivative(state: ca.SX) -> ca.SX:
        return equations(state, u, belief)

    x_next = rk4_step(derivative, x, dt)
    transition = ca.jacobian(x_next, x)

    a = ca.jacobian(derivative(x), x)
    psd = (ca.diag(ca.vertcat(*twin.noise.psd_entries()))
           + ca.diag(_force_noise(x, twin.noise, twin.bicycle)))
    term = psd
    q = ca.SX.zeros(n, n)
    factor = dt
    for k in range(NOISE_SERIES_TERMS):
        q = q + factor * term
        term = a @ term + term @ a.T
        factor = factor * dt / (k + 2)
    q = 0.5 * (q + q.T)

    # Shared where it is built, as the sub-step: the UKF's library calls it through a
    # map, which its generation leaves as it is (cosim.core.compiled_function).
    mean_step = ca.Function("bicycle_mean_step", [x, u, dt, belief], [x_next], {"cse": True})
    mapped = None
    if sigma_point_count:
        # The command and the belief are inputs shared by every point (not repeated).
        mapped = mean_step.map("bicycle_mean_steps", "serial", sigma_point_count, [1, 3],
                               [])
    return _ProcessFunctions(
        belief_names=record.names,
        belief_values=record.values,
        derivative=ca.Function("bicycle_derivative", [x, u, belief],
                               [derivative(x), ca.densify(a)]),
        # Its repeated subexpressions shared where it is built: the covariance step
        # (_covariance_step) calls this very function, so the library's C holds it once
        # (cosim.core.compiled_function.subexpressions_shared), shared, for both.
        step=ca.Function("bicycle_step", [x, u, dt, belief],
                         [x_next, ca.densify(transition), ca.densify(q)], {"cse": True}),
        mean_step=mean_step,
        noise=ca.Function("bicycle_noise", [x, u, dt, belief], [ca.densify(q)]),
        psd=ca.Function("bicycle_psd", [x, belief], [ca.densify(psd)]),
        mapped_mean_step=mapped,
        cornering_drag=ca.Function("bicycle_cornering_drag", [x, belief],
                                   [_cornering_drag(x, twin.bicycle)]),
        transition_sparsity=transition.sparsity(),
    )


def _covariance_step(functions: _ProcessFunctions) -> ca.Function:
    """The EKF's whole sub-step as one function, ``(x, P, u, dt_s, accel_move, belief) ->
    (x', P')``, for its compiled prediction (:meth:`ProcessModel.covariance_step`):

    1. the acceleration moved by its commands' lag over the sub-step
       (:mod:`estimation.accel_commands`): ``x[a] += m``, ``P[a, a] += v`` with
       ``accel_move = (m, v)``;
    2. the sub-step of :func:`_process_functions` (``x1, F, Q``) and filterpy's
       ``P1 = F P F' + Q`` (``ExtendedKalmanFilter.predict``), over the entries of ``F``
       that are not structurally zero;
    3. the angles wrapped to (-pi, pi] and ``P' = (P1 + P1') / 2``
       (:meth:`estimation.fusion.KalmanFusion._normalise`).

    One call where the three steps in numpy took three, and their products in C: the
    EKF's prediction some 15 us a sub-step faster. An MX function that calls the sub-step
    (not a copy of its 50,000 operations: the library builds in the same time). Built only
    when the filter's library is not on disk yet (else taken from it), once per
    ``functions`` (:attr:`_ProcessFunctions.covariance_step`): it calls their very ``step``,
    so a library generated from both holds the sub-step once."""
    step = functions.step
    n = len(STATE_NAMES)
    x = ca.MX.sym("x", n)
    p = ca.MX.sym("p", n, n)
    u = ca.MX.sym("u", step.size1_in(1))
    dt = ca.MX.sym("dt_s")
    move = ca.MX.sym("accel_move", 2)
    belief = ca.MX.sym("belief", step.size1_in(3))
    accel = state_index("ax_mps2")
    moved_x = x + ca.DM(ca.Sparsity.triplet(n, 1, [accel], [0]), 1.0) * move[0]
    moved_p = p + ca.DM(ca.Sparsity.triplet(n, n, [accel], [accel]), 1.0) * move[1]
    # The sub-step called, not expanded: its C is the library's bicycle_step, not a copy.
    x1, transition, noise = step(moved_x, u, dt, belief)
    # F is dense as the step gives it, a third of its entries structurally nonzero: the
    # products skip the rest (the same sums: a structural zero adds nothing).
    transition = ca.project(transition, functions.transition_sparsity)
    p1 = ca.mtimes(ca.mtimes(transition, moved_p), transition.T) + noise
    angles = {state_index(name) for name in ANGLE_STATES}
    wrapped = ca.vertcat(*[wrap_angle_symbolic(x1[i]) if i in angles else x1[i]
                           for i in range(n)])
    return ca.Function(COVARIANCE_STEP, [x, p, u, dt, move, belief],
                       [wrapped, ca.densify(0.5 * (p1 + p1.T))])


class ProcessModel:
    """The dynamic-bicycle process model with its CasADi-built discretisation.

    The CasADi functions are built once per process (:func:`_process_functions`), when
    first evaluated; :meth:`step`, :meth:`noise` and :meth:`propagate` only evaluate them.
    Every number of the noise, the bicycle and the residual's time constant is an input of
    the functions (:attr:`belief_names`), not a constant, so their structure, and the C the
    filters' functions are compiled to (:meth:`compiled_functions`,
    :meth:`sigma_point_functions`), is the same for every belief. With ``library`` (the
    filter's library as an earlier process built it from these functions:
    :func:`estimation.compiled_models.recorded`), the functions the filter compiles are
    taken from it (``casadi.external``, the C the compiled call runs) and their graphs
    are not built at all: some 40 ms of a new process's set-up.
    """

    def __init__(
        self,
        noise: ProcessNoise,
        bicycle: BicycleParams,
        residual_time_constant_s: float,
        sigma_point_count: int = 0,
        steering: SteeringBelief | None = None,
        library: Path | None = None,
    ) -> None:
        if not (
            math.isfinite(residual_time_constant_s)
            and residual_time_constant_s >= MIN_RESIDUAL_TIME_CONSTANT_S
        ):
            raise ValueError(
                f"residual_time_constant_s = {residual_time_constant_s!r}: expected a number "
                f">= {MIN_RESIDUAL_TIME_CONSTANT_S}"
            )
        if sigma_point_count < 0:
            raise ValueError(f"sigma_point_count = {sigma_point_count}: expected >= 0")
        self.noise = noise
        self.bicycle = bicycle
        self.residual_time_constant_s = residual_time_constant_s
        self.steering = SteeringBelief() if steering is None else steering
        """The steering actuator the commands drive (:mod:`estimation.steering_model`)."""
        self._numbers = _Belief(noise, bicycle, float(residual_time_constant_s), self.steering)
        self._sigma_point_count = sigma_point_count
        record = symbolic_twin(self._numbers)  # the names and values the functions take
        self.belief_names: tuple[str, ...] = record.names
        """The numbers of the ``belief`` input of the model's functions, in order."""
        self.belief_values: np.ndarray = record.values.copy()
        """Their values: this model's noise, bicycle, residual time constant and steering."""
        self._library = library
        self._evaluators: dict[str, DenseFunction] = {}
        """The functions evaluated so far, by name (:meth:`_evaluator`)."""
        self._last_input: tuple[float | None, np.ndarray] = (None, command_input(None))
        """The input vector of the last command asked for (a command is held for several
        sub-steps: its vector is made once)."""

    @functools.cached_property
    def _functions(self) -> _ProcessFunctions:
        return _process_functions(self._numbers, self._sigma_point_count)

    @property
    def derivative_function(self) -> ca.Function:
        """``(x, u, belief) -> (x_dot, A)``: the time derivative and its Jacobian."""
        return self._functions.derivative

    @property
    def step_function(self) -> ca.Function:
        """One sub-step, ``(x, u, dt_s, belief) -> (x_next, F, Q)``: the EKF's prediction
        (``u``: :data:`estimation.steering_model.COMMAND_INPUTS`)."""
        return self._functions.step

    def _evaluator(self, name: str) -> DenseFunction:
        """The function ``name`` (``bicycle_step`` ...) on buffers of its own, with this
        model's belief: from the recorded library if the filter compiles it (the EKF: the
        sub-step and the cornering drag; the UKF: the noise, the mapped sub-step and the
        drag), else from the functions built once per process."""
        evaluator = self._evaluators.get(name)
        if evaluator is None:
            compiled = (_SIGMA_POINT_COMPILED if self._sigma_point_count else _COMPILED)
            if self._library is not None and name in compiled:
                function = external_function(name, self._library)
            elif name == COVARIANCE_STEP:
                function = _process_functions(self._numbers, 0).covariance_step
            else:
                function = self._functions.named(name)
            evaluator = DenseFunction(function, parameters=self.belief_values)
            self._evaluators[name] = evaluator
        return evaluator

    @functools.cached_property
    def _step_fast(self) -> DenseFunction:
        return self._evaluator("bicycle_step")

    @functools.cached_property
    def _covariance_step_fast(self) -> DenseFunction:
        return self._evaluator(COVARIANCE_STEP)

    @functools.cached_property
    def _drag_fast(self) -> DenseFunction:
        return self._evaluator("bicycle_cornering_drag")

    @functools.cached_property
    def _mapped_step(self) -> DenseFunction | None:
        return self._evaluator("bicycle_mean_steps") if self._sigma_point_count else None

    def use_noise(self, noise: ProcessNoise) -> None:
        """From now on, the process noise ``noise`` (the same functions, compiled or not:
        the noise's numbers are their ``belief`` input)."""
        values = self.belief_values.copy()
        for name, value in vars(noise).items():
            values[self.belief_names.index(f"noise.{name}")] = value
        self.noise, self.belief_values = noise, values
        for evaluator in self._evaluators.values():  # later ones take belief_values
            evaluator.set_parameters(values)

    def compiled_functions(self) -> tuple[DenseFunction, ...]:
        """The evaluators worth compiling to C (the EKF's sub-step, alone and with its
        covariance, and the cornering drag of every acceleration command), for
        :meth:`cosim.core.dense_function.DenseFunction.use_compiled`."""
        return (self._step_fast, self._drag_fast, self._covariance_step_fast)

    def covariance_step(self, x: np.ndarray, p: np.ndarray, dt_s: float,
                        command_rad: float | None,
                        accel_move: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        """The EKF's sub-step of the mean and covariance in one call (:func:`_covariance_step`):
        the acceleration moved by ``accel_move`` (mean, variance), the RK4 sub-step with
        ``F P F' + Q``, the angles wrapped and the covariance symmetrised."""
        self._check_step(dt_s)
        mean, covariance = self._covariance_step_fast(
            x, p, self._input(command_rad), dt_s, np.array(accel_move, dtype=float))
        return mean.reshape(-1), covariance

    def sigma_point_functions(self) -> tuple[DenseFunction, ...]:
        """The UKF's evaluators worth compiling to C: the process noise, the sub-step of
        every sigma point (:meth:`propagate`) and the cornering drag."""
        mapped = () if self._mapped_step is None else (self._mapped_step,)
        return (self._evaluator("bicycle_noise"), *mapped, self._drag_fast)

    def derivative(self, x: np.ndarray,
                   command_rad: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The noise-free time derivative of the state and its Jacobian ``A`` at ``x``, the
        steering driven by ``command_rad`` (None: no command, :mod:`estimation.steering_model`)."""
        f, a = self._evaluator("bicycle_derivative")(np.asarray(x, dtype=float).reshape(-1),
                                     self._input(command_rad))
        return f.reshape(-1), a

    def _input(self, command_rad: float | None) -> np.ndarray:
        """The input vector of ``command_rad`` (:func:`command_input`), made once per
        command."""
        last_rad, vector = self._last_input
        if command_rad is not last_rad and command_rad != last_rad:
            vector = command_input(command_rad)
            self._last_input = (command_rad, vector)
        return vector

    @staticmethod
    def _check_step(dt_s: float) -> None:
        if not 0.0 <= dt_s <= MAX_STEP_S * (1.0 + 1e-9):
            raise ValueError(f"dt_s = {dt_s!r}: expected a sub-step in [0, {MAX_STEP_S}] s")

    def step(self, x: np.ndarray, dt_s: float, command_rad: float | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One sub-step: the predicted mean (column), its Jacobian F and the noise Q, the
        steering driven by ``command_rad`` through the sub-step (None: no command).

        ``dt_s`` must not exceed :data:`MAX_STEP_S` (the filters split longer intervals).
        """
        self._check_step(dt_s)
        return self._step_fast(x, self._input(command_rad), dt_s)

    def cornering_drag_mps2(self, x: np.ndarray) -> float:
        """The front tyres' lateral force along the car per unit mass at ``x``,
        ``-F_yf sin(delta) / m`` [m/s^2] (:func:`_cornering_drag`)."""
        return float(self._drag_fast.first(np.asarray(x, dtype=float).reshape(-1))[0])

    def noise_psd(self, x: np.ndarray) -> np.ndarray:
        """The white-noise PSD matrix ``W`` at ``x`` (diagonal; some entries grow with the
        tyre forces, see :class:`ProcessNoise`)."""
        return self._evaluator("bicycle_psd")(np.asarray(x, dtype=float).reshape(-1))[0]

    def process_noise(self, x: np.ndarray, dt_s: float,
                      command_rad: float | None = None) -> np.ndarray:
        """The discrete process noise Q of a sub-step, linearised at ``x`` (and the
        steering command ``command_rad``, None: none).

        For a model without sigma points (the EKF's) it is the ``Q`` of :meth:`step`, the
        same expression evaluated with the mean and its Jacobian: the sub-step the EKF
        evaluates (compiled) at every prediction serves the rare call here, and the noise
        function is never built for it; the UKF's is its own compiled noise function."""
        self._check_step(dt_s)
        if not self._sigma_point_count:
            return self._step_fast(x, self._input(command_rad), dt_s)[2]
        return self._evaluator("bicycle_noise")(x, self._input(command_rad), dt_s)[0]

    def propagate(self, points: np.ndarray, dt_s: float,
                  command_rad: float | None = None) -> np.ndarray:
        """The RK4 sub-step of every row of ``points`` (one state per row), in one call, the
        steering driven by ``command_rad`` (None: no command).

        Uses the Function mapped over ``sigma_point_count`` points if ``points`` has that
        many rows, else one call per point.
        """
        self._check_step(dt_s)
        points = np.asarray(points, dtype=float)
        if points.ndim != 2 or points.shape[1] != len(STATE_NAMES):
            raise ValueError(
                f"points of shape {points.shape}: expected (count, {len(STATE_NAMES)})"
            )
        mapped, command = self._mapped_step, self._input(command_rad)
        if mapped is not None and points.shape[0] == mapped.function.size_in(0)[1]:
            return mapped.rows(points, command, np.full(points.shape[0], dt_s))[0]
        mean_step = self._evaluator("bicycle_mean_step")
        return np.vstack([mean_step(p, command, dt_s)[0].reshape(-1) for p in points])


def _cornering_drag(x: ca.SX, bicycle: BicycleParams) -> ca.SX:
    """``-F_yf sin(delta) / m``: the front tyres' lateral force, perpendicular to the
    steered wheels, has this component along the car. A drive asked for an acceleration
    ``a`` gives ``a`` plus this in a turn (the low-level layer's model of the road loads
    holds no cornering drag): on the MuJoCo sedan ``a_x - a`` is 0.94 times it, RMS 0.014
    m/s^2 left, where it was 0.16 on the circuit and 0.04 in the lane change."""
    s = named_states(x)
    force_front, _, _ = axle_forces(s, bicycle)
    return -force_front * ca.sin(s["steer_rad"]) / bicycle.mass_kg


def _force_noise(x: ca.SX, noise: ProcessNoise, bicycle: BicycleParams) -> ca.SX:
    """The state-dependent part of W's diagonal: the lateral residual's PSD grows with
    the square of the tyres' lateral acceleration (a relative error of the tyre model's
    force, e.g. of its cornering stiffness, is an error proportional to the force), the
    heading's, the yaw and roll accelerations' with the forces that drive them, the jerk's
    with the longitudinal acceleration (:class:`ProcessNoise`)."""
    s = named_states(x)
    force_front, force_rear, _ = axle_forces(s, bicycle)
    tyre_accel = (force_front + force_rear) / bicycle.mass_kg
    yaw_accel = (
        bicycle.cog_front_m * force_front - bicycle.cog_rear_m * force_rear
    ) / bicycle.yaw_inertia_kgm2
    extra = ca.SX.zeros(len(STATE_NAMES))
    extra[state_index("lateral_accel_residual_mps2")] = (
        noise.lateral_residual_relative_psd_1ps * tyre_accel**2
    )
    extra[state_index("yaw_rad")] = noise.yaw_transient_psd_s3 * yaw_accel**2
    extra[state_index("yaw_rate_radps")] = (
        noise.yaw_moment_relative_psd_s
        + noise.yaw_moment_load_transfer_psd_s5pm2 * s["ax_mps2"] ** 2
    ) * ((bicycle.cog_front_m * force_front) ** 2 + (bicycle.cog_rear_m * force_rear) ** 2
         ) / bicycle.yaw_inertia_kgm2**2
    roll = bicycle.roll
    commanded_roll_accel = roll.angular_frequency_radps**2 * roll.gradient_radpmps2 * tyre_accel
    extra[state_index("roll_rate_radps")] = (
        noise.roll_accel_relative_psd_s * commanded_roll_accel**2
    )
    extra[state_index("ax_mps2")] = noise.jerk_relative_psd_1ps * s["ax_mps2"] ** 2
    extra[state_index("steer_rad")] = (noise.steer_rate_relative_psd_s
                                       * s["steer_rate_radps"] ** 2)
    return extra


def _derivative(x: ca.SX, command: ca.SX, bicycle: BicycleParams,
                residual_time_constant_s: ca.SX, steering: SteeringBelief) -> ca.SX:
    """The time derivative of the state without noise, (D1)-(D6), (R1)-(R2), the steering
    driven by ``command`` (:data:`estimation.steering_model.COMMAND_INPUTS`) where there is
    one, (S1)-(S3) of :mod:`estimation.steering_model`."""
    s = named_states(x)
    velocity_east, velocity_north = world_velocity(s)
    r = s["yaw_rate_radps"]
    forces = axle_forces(s, bicycle)
    force_front, force_rear, front_split = forces
    vx_change = s["ax_mps2"] + r * s["vy_mps"]
    roll_change = roll_accel(s, bicycle, forces)  # (R2)
    deflection_rate = gyro_deflection_rate(s["vx_mps"], vx_change, s["roll_rate_radps"],
                                           roll_change, steering)
    steer_change, steer_rate_change = steering_derivatives(
        s["steer_rad"], s["steer_rate_radps"], command, steering,
        gyro_deflection(s["vx_mps"], s["roll_rate_radps"], steering), deflection_rate)
    return stacked_states(
        {
            "x_m": velocity_east,  # (D6)
            "y_m": velocity_north,
            "yaw_rad": r,
            "vx_mps": vx_change,
            "vy_mps": cog_lateral_accel(s, bicycle, forces) - r * s["vx_mps"],  # (D4)
            "yaw_rate_radps": yaw_moment(force_front, force_rear, front_split, s,
                                         bicycle) / bicycle.yaw_inertia_kgm2,  # (D5')
            "ax_mps2": 0.0,
            "steer_rad": steer_change,
            "steer_rate_radps": steer_rate_change,
            "roll_rad": s["roll_rate_radps"],
            "roll_rate_radps": roll_change,
            "lateral_accel_residual_mps2": (
                -s["lateral_accel_residual_mps2"] / residual_time_constant_s
            ),
            "gyro_bias_radps": 0.0,
            "ax_bias_mps2": 0.0,
            "ay_bias_mps2": 0.0,
            "rolling_radius_scale": 0.0,
            "wheel_track_scale": 0.0,
        }
    )
