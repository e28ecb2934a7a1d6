"""The NLP machinery every nonlinear MPC path tracker shares.

Tracking MPC by multiple shooting as in Rawlings, Mayne, Diehl, "Model Predictive Control:
Theory, Computation, and Design", 2nd ed., Nob Hill 2017; on a kinematic bicycle as in
Kong, Pfeiffer, Schildbach, Borrelli, "Kinematic and dynamic vehicle models for autonomous
driving control design", IEEE Intelligent Vehicles Symposium 2015.

At every control step solve, by multiple shooting with the NLP solver ``tracker.solver``,
``min_{x,u} sum_k c_k(x_k, u_k)  s.t.  x_{k+1} = F(x_k, u_k), x_0 = estimated state``,
apply the first input and keep the rest as the next warm start. A tracker is an
:class:`NmpcModel` (the model ``F`` and how its state is formed from an estimate) plus a
:class:`tracker.config.TrackerConfig`; :class:`Nmpc` does the rest:

* Reference: the estimate is projected onto the path; reference points are laid along it
  at the arc lengths the car is expected to cover, ``s_k = s_0 + sum v_j dt`` with ``v_j``
  the speeds of the warm start (the previous plan, or the current speed on the first step).
  This replaces a cubic fitted to the waypoints in the vehicle frame; the path is already a spline.
* Cost (the exact form is in :mod:`tracker.config`): cross-track error measured
  from each reference point's tangent, heading error (the path yaw is unwrapped along the
  horizon and shifted by whole turns to within pi of the current yaw, so the difference is
  smooth and needs no wrapping inside the NLP), speed error to the reference's speed profile,
  acceleration and steering, and their rates; the first rate is taken against the
  previously applied command.
* Bounds: steering ``|delta| <= max_steer_rad`` (pi/8 by default), acceleration in
  ``[accel_min_mps2, accel_max_mps2]``, steering rate ``|delta_k - delta_{k-1}| <=
  max_steer_rate_radps dt``.
* Model limits (optional, ``NmpcModel.limits``): ``|h(x_k)| <= h_max`` at nodes 1..N, soft:
  the excess costs ``dt * weights.limit_excess * max(|h| - h_max, 0)^2`` (a quadratic
  exterior penalty, continuously differentiable), so a car already beyond a limit never
  makes the NLP infeasible, and the NLP gains no variables (slack variables doubled
  IPOPT's iterations, 5 -> 10 per step on the lane change, with the same result). The
  dynamic model keeps its tyres within their linear range this way.
* Initial state: the states the model reads from the estimate, by name
  (``NmpcModel.estimated_state_names``); the model's other states (e.g. the steering
  actuator's angle, which no estimator reports) are *internal*: the tracker carries them
  itself, propagating last step's state with the command it applied (exact for an
  actuator driven by that command), and starts them at rest at the last applied input.
* Latency: with ``latency_compensation`` the tracker believes the
  car receives each command ``latency_s`` after it was issued (the runner's delay line,
  ``plant.actuator_delay_s``), plus the actuator lag the model leaves out
  (``unmodelled_lag_s``, approximated as more delay). The estimate is predicted forward
  from its time to ``t_s`` plus that delay, piece by piece with the commands already on
  their way (:class:`tracker.mpc.delay_line.IssuedInputs`), not the last one held: the
  optimisation then decides the input the car applies once the delay has passed. The
  internal states are propagated with the same applied commands.
* Caution: each solve's steering-rate weight is the configured one times ``1 +
  sigma_lat^2 / sigma_0^2``, ``sigma_lat`` the estimate's standard deviation across the
  car (:mod:`tracker.mpc.caution`, ``tracker.caution_lateral_sigma_m``): the wheel is
  calm while the estimate is unsure.
* Warm start: the previous solution shifted by the time elapsed; on the first step the
  last applied actuation held over the horizon and rolled out through the model (section
  1, "warm start").
* Failures (:mod:`tracker.mpc.base`, the skeleton every MPC shares): the solver's status
  is checked every step; a failure, a numerical error or a non-finite result replays the
  last good plan, shifted by the elapsed time (``fallback=True``); once failures have
  lasted longer than ``fallback_time_s`` the tracker commands a safe stop. A solver
  failure never raises.

Nothing depends on wall-clock time except the reported ``solve_time_s``, so equal inputs
give equal outputs.
"""

from __future__ import annotations

import math
from types import MappingProxyType

import numpy as np

from cosim.core.dense_function import DenseFunction, densified
from cosim.core.exceptions import ConfigError
from tracker.config import TrackerConfig
from tracker.models.dynamic_bicycle import steady_understeer_rad
from tracker.mpc.base import Solved, Start
from tracker.mpc.fallback import INPUT_NAMES
from tracker.mpc.grip_speed import CurvatureTable, capped_reference_speed
from tracker.mpc.horizon_reference import horizon_reference
from tracker.mpc.nmpc_model import NmpcModel
from tracker.mpc.nmpc_problem import WEIGHT_NAMES, NmpcProblem
from tracker.mpc.starting_state import EstimatedStartMpc
from tracker.paths.reference_path import ReferencePath

__all__ = ["INPUT_NAMES", "Nmpc", "NmpcModel"]

_TIME_EPS_S = 1e-9
"""Slack when comparing simulated times, against float round-off of sums of periods."""


class Nmpc(EstimatedStartMpc):
    """Nonlinear MPC path tracker on any :class:`NmpcModel` (Kong et al. 2015), solved by
    ``config.solver`` (IPOPT, fatrop or a real-time iteration; module docstring).

    Args:
      config: the tracker configuration (horizon, cost, bounds, solver, latency).
      model: the vehicle model; its ``dt_s`` must be ``config.dt_s``.

    The plan's node 0 is the state the optimisation started from: the estimate predicted
    over the latency (see the module docstring), i.e. the car at ``t_s + latency``; the
    plan's ``t_s`` and the command's ``t_s`` are the time of the step. A successful solve
    ends a fallback or a safe stop (:mod:`tracker.mpc.base`).
    """

    def __init__(self, config: TrackerConfig, model: NmpcModel) -> None:
        if not math.isclose(model.dt_s, config.dt_s, rel_tol=0.0, abs_tol=_TIME_EPS_S):
            raise ConfigError(f"model {model.name}: dt_s = {model.dt_s}, expected "
                              f"tracker.dt_s = {config.dt_s}")
        self.model = model
        self.state_names: tuple[str, ...] = model.state_names
        self.input_names: tuple[str, ...] = model.input_names
        self._state = MappingProxyType({name: i for i, name in enumerate(model.state_names)})
        self._step = DenseFunction(densified(model.step)).first  # a stage, numerically
        self._problem = NmpcProblem(config, model)
        self._params = self._problem.params
        self._nlp = self._problem.build()
        low, high = self._problem.input_bounds()
        latency_s = config.latency_s if config.latency_compensation else 0.0
        super().__init__(config, config.dt_s, config.horizon, low, high,
                         self._state["vx_mps"], latency_s + model.unmodelled_lag_s)
        self._init_start(f"tracker model {model.name}", model.state_names,
                         model.estimated_state_names, model.internal_rest_inputs,
                         model.predict)
        self._curvature: CurvatureTable | None = None
        self._steer_rate_index = WEIGHT_NAMES.index("steer_rate")
        self._weights = self._problem.weight_values.copy()
        """This step's weights: the configured ones, the steering rate's times the start's
        caution (:attr:`Start.caution`)."""
        self.reset()

    # ------------------------------------------------------------------ the step

    def _solve(self, t_s: float, start: Start, reference: ReferencePath) -> Solved:
        state0 = start.state
        cold = self._warm is None  # no plan to shift: the guess is the last input held
        guess = self._warm_start(t_s, state0, self._step, self._state["yaw_rad"])
        blocks, speed_reduced = self._reference_blocks(reference, state0, guess.states, t_s)
        blocks["state0"] = state0
        blocks["input_prev"] = self._previous_input
        blocks["belief"] = self._problem.belief_values
        index = self._steer_rate_index
        self._weights[index] = self._problem.weight_values[index] * start.caution
        blocks["weights"] = self._weights
        params = self._params.pack(blocks)
        nlp = self._nlp
        w0 = nlp.pack(guess.states, guess.inputs, self._previous_input)
        solution = nlp.solve(w0, params, cold)
        w = solution.w
        return Solved(w[nlp.state_index], w[nlp.input_index], solution.cost, solution.status,
                      solution.iterations, solution.success, solution.solve_time_s,
                      speed_reduced=speed_reduced)

    def _rollout(self, start: Start, inputs: np.ndarray) -> np.ndarray:
        states = np.empty((inputs.shape[0] + 1, len(self.state_names)))
        states[0] = start.state
        for k, u in enumerate(inputs):
            states[k + 1] = self._step(states[k], u)
        return states

    def _reference_blocks(
        self, reference: ReferencePath, state0: np.ndarray, guess_states: np.ndarray,
        t_s: float,
    ) -> tuple[dict[str, np.ndarray], bool]:
        """Reference points at the arc lengths the warm start expects to cover
        (:mod:`tracker.mpc.horizon_reference`), the reference speed there (the path's speed
        profile at each stage's arc length and time, capped by the friction-limited speed
        of the path ahead with ``grip.speed_planning``, :mod:`tracker.mpc.grip_speed`), and
        the steering they need in a steady turn; and whether the cap lowered the speed."""
        cfg = self.config
        index = self._state
        speed = guess_states[:, index["vx_mps"]]
        points = horizon_reference(cfg.reference, reference, state0[index["x_m"]],
                                   state0[index["y_m"]], state0[index["yaw_rad"]], speed,
                                   cfg.dt_s)
        steer = np.zeros(self._n)
        if cfg.curvature_feedforward:
            kappa = points.curvature_1pm
            steer = np.arctan(cfg.model.wheelbase_m * kappa) + steady_understeer_rad(
                self.model.understeer_gradient_radpmps2, speed[1:], kappa,
                self.model.steady_grip_mps2)
        ref_speed = points.speed_mps(reference, t_s, cfg.dt_s)
        speed_reduced = False
        if cfg.grip.speed_planning:
            if self._curvature is None or self._curvature.path is not reference:
                self._curvature = CurvatureTable(reference)  # once per path
            cap = capped_reference_speed(self._curvature, points.s_m, ref_speed,
                                         float(state0[index["vx_mps"]]),
                                         cfg.model.tyre_friction, cfg.grip)
            ref_speed, speed_reduced = cap.speed_mps, cap.reduced
        return {
            "ref_x_m": points.x_m,
            "ref_y_m": points.y_m,
            "ref_yaw_rad": points.yaw_rad,
            "ref_speed_mps": ref_speed,
            "ref_steer_rad": steer,
        }, speed_reduced
