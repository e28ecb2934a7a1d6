"""Fits of the identification: pure functions from measured data to model parameters.

Nothing here touches the plant; the same functions are tested on synthetic data generated
by the models themselves (tests/identification/test_identify.py). Every fit returns a
frozen record with its parameters, the RMS of its residual in the fitted quantity's units
and its number of samples.

- :func:`fit_wheelbase`: the kinematic bicycle (Rajamani, "Vehicle
  Dynamics and Control", 2nd ed., ch. 2, kinematic model) referenced at the centre of
  gravity (CoG) drives a circle of radius ``R = sqrt(l_r^2 + L^2 cot^2 delta)``; with the
  CoG position known as a share of the wheelbase, ``l_r = q L``, this is linear in ``L``:
  ``R = L sqrt(q^2 + cot^2 delta)`` (W1), solved by linear least squares on the radii of
  low-speed steady circles.
- :func:`fit_cornering_stiffness`: the linear-tyre dynamic bicycle
  (:mod:`tracker.models.dynamic_bicycle`; Rajamani 2012, sec. 2.3) with known mass, yaw inertia and
  CoG position; ``C_f``, ``C_r`` by ``scipy.optimize.least_squares`` on steady turns
  (closed forms (S2)-(S3) of yaw rate and lateral velocity) and on transients (the CasADi
  model simulated by RK4 from the measured road-wheel angle and speed), with the exact
  Jacobian from CasADi.
- :func:`fit_first_order_lag`: an actuator path ``y' = (g u(t - T_d) + o - y) / tau`` with
  an optional rate limit ``|y'| <= rho``, discretised exactly as the plant's steering
  actuator is (exact first-order step, then the rate clip); dead time ``T_d`` in whole
  samples by a grid search around the first visible response, the rest by least squares.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.optimize import least_squares
from scipy.signal import lfilter

from cosim.core.vehicle_params import VehicleParams
from cosim.identification.data import (
    IdentificationError,
    LateralResponse,
    SteadyTurn,
    StepResponse,
)
from tracker.models.dynamic_bicycle import (
    LATERAL_STATE,
    PARAM_NAMES,
    DynamicBicycleParams,
    lateral_discrete_function,
    steady_lateral_velocity,
    steady_yaw_rate_gain,
)

FITTED_NAMES: tuple[str, ...] = ("cornering_stiffness_front_npr", "cornering_stiffness_rear_npr")
"""The dynamic bicycle's parameters the cornering fit estimates, in its vector order."""

REFERENCE_STIFFNESS_NPR = 1e5
"""Scale of the cornering-stiffness parameters: the fit works on ``log(C / 1e5 N/rad)``,
which keeps both stiffnesses positive and of order one [N/rad]."""

STIFFNESS_BOUNDS_NPR = (1e3, 1e8)
"""Bounds of a fitted axle cornering stiffness (a bicycle tyre to a rigid wheel) [N/rad]."""

MAX_INTEGRATION_STEP_S = 0.0025
"""Longest RK4 step of the transient simulation: stiff tyres (1.5e6 N/rad per axle at
10 m/s) give lateral modes near -170 1/s, and RK4 is accurate for |lambda h| < 0.5 [s]."""

RESPONSE_ONSET_FRACTION = 0.01
"""A response has begun once it moved by this fraction of its final change."""

RATE_LIMIT_MIN_IMPROVEMENT = 0.1
"""A rate limit is reported only if it lowers the residual by at least this fraction;
otherwise it did not bind on the data and cannot be identified from it."""

EXPLAINED_FRACTION = 1e-6
"""A lag whose residual is below this fraction of the largest response swing already
explains the data: there is nothing left for a rate limit to explain."""


# ------------------------------------------------------------------ kinematic bicycle


@dataclass(frozen=True)
class WheelbaseFit:
    """Effective wheelbase of the kinematic bicycle from steady circles."""

    effective_wheelbase_m: float
    radius_residual_rms_m: float
    samples: int


def fit_wheelbase(turns: Sequence[SteadyTurn], rear_share: float) -> WheelbaseFit:
    """Least-squares ``L`` of (W1) from steady circles at low speed.

    ``rear_share`` is ``l_r / L``, the CoG's distance to the rear axle as a share of the
    wheelbase (equal to the front axle's share of the static load).
    """
    if not 0.0 < rear_share < 1.0:
        raise IdentificationError(f"rear_share = {rear_share!r}: expected a share in (0, 1)")
    if len(turns) < 1:
        raise IdentificationError("fit_wheelbase: expected at least one steady circle")
    steer = np.array([turn.steer_rad for turn in turns])
    if np.any(np.abs(steer) < 1e-4):
        raise IdentificationError("fit_wheelbase: a circle has no steering angle")
    radius = np.array([turn.radius_m for turn in turns])
    shape = np.sqrt(rear_share**2 + 1.0 / np.tan(np.abs(steer)) ** 2)  # (W1): R = L shape
    (wheelbase,), *_ = np.linalg.lstsq(shape[:, None], radius, rcond=None)
    residual = wheelbase * shape - radius
    return WheelbaseFit(
        effective_wheelbase_m=float(wheelbase),
        radius_residual_rms_m=_rms(residual),
        samples=len(turns),
    )


# ------------------------------------------------------------- dynamic bicycle tyres


@dataclass(frozen=True)
class CorneringFit:
    """Axle cornering stiffnesses of the linear-tyre dynamic bicycle and the fit's quality.

    Residuals are model minus measurement: of the steady-state yaw-rate gain r/delta over
    the steady turns, and of yaw rate and lateral velocity over the transient samples.
    """

    model: DynamicBicycleParams
    yaw_rate_gain_residual_rms_per_s: float
    steady_samples: int
    transient_yaw_rate_residual_rms_radps: float
    transient_lateral_velocity_residual_rms_mps: float
    transient_samples: int
    solver_status: str


def _stiffness_guess(turns: Sequence[SteadyTurn], vehicle: VehicleParams) -> tuple[float, float]:
    """Axle stiffnesses from the slip angles of the steady turns (median), or 1e5 N/rad.

    In a steady turn the axles carry ``F_yf = m a_y l_r / L`` and ``F_yr = m a_y l_f / L``
    at the slip angles (D1)-(D2) of the measured ``vy``, ``r`` and ``delta``.
    """
    m, l_f, l_r = vehicle.mass_kg, vehicle.cog_front_m, vehicle.cog_rear_m
    wheelbase = l_f + l_r
    front, rear = [], []
    for turn in turns:
        ay = turn.vx_mps * turn.yaw_rate_radps
        alpha_f = turn.steer_rad - (turn.vy_mps + l_f * turn.yaw_rate_radps) / turn.vx_mps
        alpha_r = -(turn.vy_mps - l_r * turn.yaw_rate_radps) / turn.vx_mps
        if alpha_f * ay > 0.0:
            front.append(m * ay * l_r / wheelbase / alpha_f)
        if alpha_r * ay > 0.0:
            rear.append(m * ay * l_f / wheelbase / alpha_r)
    low, high = STIFFNESS_BOUNDS_NPR

    def pick(values: list[float]) -> float:
        return float(np.clip(np.median(values), low, high)) if values else REFERENCE_STIFFNESS_NPR

    return pick(front), pick(rear)


def fit_cornering_stiffness(
    turns: Sequence[SteadyTurn],
    responses: Sequence[LateralResponse],
    vehicle: VehicleParams,
) -> CorneringFit:
    """``C_f``, ``C_r`` of the dynamic bicycle from steady turns and lateral transients.

    Mass, yaw inertia and CoG position are those of ``vehicle`` (known, not fitted). Every
    residual is expressed as an equivalent steering angle relative to the run's steering
    amplitude (yaw rate times ``L / vx``, lateral velocity over ``vx``), so runs at
    different speeds and amplitudes weigh alike; each steady turn counts as one residual
    per signal and each transient as one (its samples weighted by ``1/sqrt(n)``).
    Between samples the transient model holds the mean of the two samples' road-wheel
    angle and speed.
    """
    if len(turns) + len(responses) == 0:
        raise IdentificationError("fit_cornering_stiffness: expected steady turns or transients")
    if 2 * len(turns) + sum(r.samples - 1 for r in responses) < 2:
        raise IdentificationError("fit_cornering_stiffness: expected at least two residuals")
    wheelbase = vehicle.wheelbase_m
    # Fitted: log(C / 1e5 N/rad) of each axle, named as in the model's parameter vector.
    theta = {name: ca.SX.sym(f"log_{name}") for name in FITTED_NAMES}
    known = {"mass_kg": vehicle.mass_kg, "yaw_inertia_kgm2": vehicle.yaw_inertia_kgm2,
             "cog_front_m": vehicle.cog_front_m, "cog_rear_m": vehicle.cog_rear_m}
    known.update({name: REFERENCE_STIFFNESS_NPR * ca.exp(theta[name])
                  for name in FITTED_NAMES})
    params = ca.vertcat(*(known[name] for name in PARAM_NAMES))
    fitted = ca.vertcat(*(theta[name] for name in FITTED_NAMES))

    residuals = _steady_residuals(turns, params, wheelbase)
    transient, predictions = _transient_residuals(responses, params, wheelbase)
    residuals += transient

    residual = ca.vertcat(*residuals)
    residual_function = ca.Function("residual", [fitted], [residual])
    jacobian_function = ca.Function("residual_jacobian", [fitted],
                                    [ca.jacobian(residual, fitted)])

    guess = np.log(np.array(_stiffness_guess(turns, vehicle)) / REFERENCE_STIFFNESS_NPR)
    low, high = (math.log(b / REFERENCE_STIFFNESS_NPR) for b in STIFFNESS_BOUNDS_NPR)
    result = least_squares(
        lambda x: np.asarray(residual_function(x), dtype=float).ravel(),
        guess,
        jac=lambda x: np.asarray(jacobian_function(x), dtype=float),
        bounds=(low, high),
        x_scale=1.0,
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
    )
    if result.status <= 0 or not np.all(np.isfinite(result.x)):
        raise IdentificationError(f"fit_cornering_stiffness: least squares failed "
                                  f"({result.message})")
    stiffness = {name: float(REFERENCE_STIFFNESS_NPR * math.exp(x))
                 for name, x in zip(FITTED_NAMES, result.x, strict=True)}
    model = DynamicBicycleParams.from_vehicle(vehicle, **stiffness)

    gain_errors = [model.yaw_rate_gain_per_s(t.vx_mps) - t.yaw_rate_gain_per_s for t in turns]
    if predictions:
        errors = ca.Function("errors", [fitted], [ca.vertcat(*(e for e, _ in predictions)),
                                                 ca.vertcat(*(e for _, e in predictions))])
        yaw_rate_errors, vy_errors = (np.asarray(e, dtype=float).ravel()
                                      for e in errors(result.x))
    else:
        yaw_rate_errors = vy_errors = np.zeros(0)
    return CorneringFit(
        model=model,
        yaw_rate_gain_residual_rms_per_s=_rms(gain_errors),
        steady_samples=len(turns),
        transient_yaw_rate_residual_rms_radps=_rms(yaw_rate_errors),
        transient_lateral_velocity_residual_rms_mps=_rms(vy_errors),
        transient_samples=int(yaw_rate_errors.size),
        solver_status=str(result.message),
    )


def _steady_residuals(turns: Sequence[SteadyTurn], params: ca.SX,
                      wheelbase: float) -> list[ca.SX]:
    """Two residuals per steady turn, (S2) and (S3) against the measured yaw rate and
    lateral velocity, as steering-angle equivalents over the run's amplitude."""
    residuals = []
    for turn in turns:
        amplitude = abs(turn.steer_rad)
        if amplitude < 1e-6:
            raise IdentificationError("fit_cornering_stiffness: a steady turn has no steering")
        yaw_rate = steady_yaw_rate_gain(turn.vx_mps, params) * turn.steer_rad  # (S2)
        vy = steady_lateral_velocity(turn.vx_mps, yaw_rate, params)  # (S3)
        residuals.append((yaw_rate - turn.yaw_rate_radps) * wheelbase / turn.vx_mps / amplitude)
        residuals.append((vy - turn.vy_mps) / turn.vx_mps / amplitude)
    return residuals


def _transient_residuals(responses: Sequence[LateralResponse], params: ca.SX, wheelbase: float
                         ) -> tuple[list[ca.SX], list[tuple[ca.SX, ca.SX]]]:
    """Each transient simulated through the lateral model from its first sample: its
    weighted yaw-rate and lateral-velocity residuals, and the raw errors of each."""
    residuals, predictions = [], []
    for response in responses:
        n = response.samples - 1
        amplitude = float(np.max(np.abs(response.steer_rad)))
        if amplitude < 1e-6:
            raise IdentificationError("fit_cornering_stiffness: a transient has no steering")
        substeps = max(1, math.ceil(response.dt_s / MAX_INTEGRATION_STEP_S - 1e-9))
        step = lateral_discrete_function(response.dt_s, substeps).mapaccum("trajectory", n)
        steer_mid = 0.5 * (response.steer_rad[:-1] + response.steer_rad[1:])
        vx_mid = 0.5 * (response.vx_mps[:-1] + response.vx_mps[1:])
        start = np.zeros(2)
        start[LATERAL_STATE["vy_mps"]] = response.vy_mps[0]
        start[LATERAL_STATE["yaw_rate_radps"]] = response.yaw_rate_radps[0]
        trajectory = step(start, steer_mid[None, :], vx_mid[None, :], ca.repmat(params, 1, n))
        vy_model = trajectory[LATERAL_STATE["vy_mps"], :].T
        yaw_rate_model = trajectory[LATERAL_STATE["yaw_rate_radps"], :].T
        vy_error = vy_model - response.vy_mps[1:]
        yaw_rate_error = yaw_rate_model - response.yaw_rate_radps[1:]
        weight = 1.0 / (amplitude * math.sqrt(n))
        residuals.append(yaw_rate_error * wheelbase / vx_mid * weight)
        residuals.append(vy_error / vx_mid * weight)
        predictions.append((yaw_rate_error, vy_error))
    return residuals, predictions


# ------------------------------------------------------------------ actuator lags


@dataclass(frozen=True)
class LagFit:
    """A first-order actuator path: ``y' = (gain u(t - delay) + offset - y) / tau``, with
    ``|y'| <= rate_limit`` when one was identified (``None``: it did not bind)."""

    gain: float
    time_constant_s: float
    delay_s: float
    offset: float
    rate_limit_per_s: float | None
    residual_rms: float
    samples: int


def simulate_first_order(
    command: np.ndarray,
    initial: float,
    dt_s: float,
    gain: float,
    time_constant_s: float,
    delay_steps: int = 0,
    offset: float = 0.0,
    rate_limit_per_s: float | None = None,
) -> np.ndarray:
    """Response of the lag to ``command`` (one sample per ``dt_s``), starting at ``initial``.

    ``y[k+1] = y[k] + clip((1 - exp(-dt/tau)) (g u[k - d] + o - y[k]), +-rho dt)``: the
    exact step of the first-order lag, then the rate limit (as the plant's steering
    actuator does it); before the first sample the command is taken as ``command[0]``.
    """
    command = np.asarray(command, dtype=float)
    if delay_steps < 0:
        raise IdentificationError(f"delay_steps = {delay_steps}: expected >= 0")
    delayed = np.concatenate([np.full(delay_steps, command[0]), command])[: command.size]
    target = gain * delayed + offset
    blend = 1.0 - math.exp(-dt_s / time_constant_s) if time_constant_s > 0.0 else 1.0
    if rate_limit_per_s is None:
        # y[k+1] = (1 - blend) y[k] + blend target[k]
        filtered, _ = lfilter([blend], [1.0, blend - 1.0], target[:-1],
                              zi=[(1.0 - blend) * initial])
        return np.concatenate([[initial], filtered])
    max_step = rate_limit_per_s * dt_s
    out = np.empty(command.size)
    value = float(initial)
    out[0] = value
    for k in range(command.size - 1):
        step = blend * (float(target[k]) - value)
        value += min(max(step, -max_step), max_step)
        out[k + 1] = value
    return out


def _onset_delay(response: StepResponse) -> int:
    """Samples from the first change of the command to the first visible response."""
    command, measured = response.command, response.response
    changed = np.flatnonzero(command != command[0])
    if changed.size == 0:
        raise IdentificationError("fit_first_order_lag: a command never changes")
    start = int(changed[0])
    final_change = abs(float(measured[-1] - measured[start]))
    moved = np.flatnonzero(np.abs(measured[start:] - measured[start])
                           > RESPONSE_ONSET_FRACTION * max(final_change, 1e-12))
    if moved.size == 0:
        raise IdentificationError("fit_first_order_lag: the response never moves")
    return max(int(moved[0]) - 1, 0)


def fit_first_order_lag(
    responses: Sequence[StepResponse],
    *,
    fit_offset: bool = False,
    fit_rate_limit: bool = False,
    max_delay_s: float = 1.0,
) -> LagFit:
    """Gain, time constant, dead time (and offset, rate limit) of an actuator path.

    The dead time is searched over whole samples from zero to one past the first visible
    response (at most ``max_delay_s``); for each, the gain, time constant and offset are
    fitted by least squares on all responses together; the best is kept. With
    ``fit_rate_limit`` the search is repeated with a rate limit fitted with the others, and
    the rate-limited fit is kept if it lowers the residual by
    :data:`RATE_LIMIT_MIN_IMPROVEMENT` or more.
    """
    if not responses:
        raise IdentificationError("fit_first_order_lag: expected at least one response")
    dt_s = responses[0].dt_s
    if any(abs(r.dt_s - dt_s) > 1e-12 * dt_s for r in responses):
        raise IdentificationError("fit_first_order_lag: expected one sample period")
    max_delay = min(min(_onset_delay(r) for r in responses) + 1,
                    int(math.floor(max_delay_s / dt_s + 1e-9)))
    measured = np.concatenate([r.response[1:] for r in responses])

    # Parameter vectors by name: (initial guess, lower bound, upper bound, scale).
    swing = max(float(np.max(np.abs(np.diff(r.response)))) for r in responses) / dt_s
    layout = {"gain": (1.0, 1e-3, 1e3, 1.0),
              "time_constant_s": (5.0 * dt_s, 0.0, 10.0, 0.05)}
    if fit_offset:
        layout["offset"] = (0.0, -np.inf, np.inf, 1.0)
    lag_names = tuple(layout)
    layout["rate_limit_per_s"] = (swing, 1e-3, 1e3, 0.1)
    limited_names = tuple(layout)

    def named(x: np.ndarray, names: tuple[str, ...]) -> dict[str, float]:
        return {name: float(value) for name, value in zip(names, x, strict=True)}

    def residual(x: np.ndarray, delay: int, names: tuple[str, ...]) -> np.ndarray:
        p = named(x, names)
        model = np.concatenate([
            simulate_first_order(r.command, float(r.response[0]), dt_s, p["gain"],
                                 p["time_constant_s"], delay, p.get("offset", 0.0),
                                 p.get("rate_limit_per_s"))[1:]
            for r in responses
        ])
        return model - measured

    def fit(delay: int, names: tuple[str, ...],
            start: dict[str, float]) -> tuple[float, int, dict[str, float]]:
        result = least_squares(
            residual, [start.get(n, layout[n][0]) for n in names], args=(delay, names),
            bounds=([layout[n][1] for n in names], [layout[n][2] for n in names]),
            x_scale=[layout[n][3] for n in names])
        return _rms(result.fun), delay, named(result.x, names)

    lag_fits = [fit(delay, lag_names, {}) for delay in range(max_delay + 1)]
    cost, delay, best = min(lag_fits, key=lambda candidate: candidate[0])
    scale = max(float(np.ptp(r.response)) for r in responses)
    if fit_rate_limit and cost > EXPLAINED_FRACTION * scale:
        limited = min((fit(d, limited_names, start) for _, d, start in lag_fits),
                      key=lambda candidate: candidate[0])
        if limited[0] <= (1.0 - RATE_LIMIT_MIN_IMPROVEMENT) * cost:
            cost, delay, best = limited
    return LagFit(gain=best["gain"], time_constant_s=best["time_constant_s"],
                  delay_s=delay * dt_s, offset=best.get("offset", 0.0),
                  rate_limit_per_s=best.get("rate_limit_per_s"), residual_rms=cost,
                  samples=int(measured.size))


def _rms(values: Sequence[float] | np.ndarray) -> float:
    array = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(array**2))) if array.size else 0.0
