"""The state a world-frame MPC starts from: the estimate by name, the tracker's own actuator
states, predicted over the estimate's age and the latency.

The states the model reads from the estimate are taken by name; the model's other states
(e.g. the steering actuator's road-wheel angle, which no estimator reports) are *internal*:
the tracker carries them itself, propagating last step's value with the commands the car
applied since (exact for an actuator those commands drive), and starts each at rest at the
applied input its model names. The whole state is then predicted from the estimate's time
to the step's time plus the delay the tracker believes in, piece by piece with the
commands already on their way (:class:`tracker.mpc.delay_line.IssuedInputs`), not the last
one held: the optimisation then decides the input the car applies once the delay has
passed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType

import casadi as ca
import numpy as np

from cosim.core.dense_function import DenseFunction, densified
from cosim.core.exceptions import ConfigError
from cosim.core.records import Estimate
from tracker.mpc.base import MpcTracker, Start
from tracker.mpc.caution import steer_rate_factor
from tracker.mpc.delay_line import IssuedInputs
from tracker.mpc.fallback import INPUT
from tracker.paths.reference_path import ReferencePath


class StartingState:
    """Forms a model's initial state from estimates, one control step after another.

    Args:
      who: names the tracker in messages (``tracker ltv-mpc``).
      state_names: the model's states, in vector order.
      estimated_names: the states read from the estimate.
      internal_rest_inputs: each internal state and the input it rests at.
      predict: ``P(state, inputs, duration_s) -> state`` with the inputs held.
      issued: the tracker's commands and the delay it believes in.
    """

    def __init__(self, who: str, state_names: tuple[str, ...],
                 estimated_names: tuple[str, ...], internal_rest_inputs: Mapping[str, str],
                 predict: ca.Function, issued: IssuedInputs) -> None:
        self._who = who
        self._index = MappingProxyType({name: i for i, name in enumerate(state_names)})
        self._estimated = estimated_names
        self._rest_inputs = internal_rest_inputs
        self._predict_function = DenseFunction(densified(predict)).first
        self._issued = issued
        self._gathered: tuple[tuple[str, ...], np.ndarray, np.ndarray] | None = None
        self.reset()

    def reset(self) -> None:
        """Forget the last step's state (the internal states restart at rest)."""
        self._last: tuple[float, np.ndarray] | None = None

    def _gather(self, names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Where the estimated states sit in an estimate with ``names`` and in the model's
        state (found once per estimator: an estimator keeps its names); a missing one is a
        :class:`ConfigError`."""
        if self._gathered is None or self._gathered[0] != names:
            missing = [name for name in self._estimated if name not in names]
            if missing:
                raise ConfigError(f"{self._who}: the estimate has no {', '.join(missing)}: "
                                  "expected an estimator that reports them")
            self._gathered = (names,
                              np.array([names.index(n) for n in self._estimated], dtype=int),
                              np.array([self._index[n] for n in self._estimated], dtype=int))
        return self._gathered[1], self._gathered[2]

    def predict(self, state: np.ndarray, start_s: float, end_s: float) -> np.ndarray:
        """``state`` at ``start_s`` moved to ``end_s`` through the inputs the car applies
        (the delay line), one held input per piece."""
        for duration_s, inputs in self._issued.segments(start_s, end_s):
            state = self._predict_function(state, inputs, duration_s)
        return state

    def _internal_states(self, t_s: float) -> dict[str, float]:
        """The internal states at ``t_s``: last step's propagated through the applied
        commands, else at rest at the input applied now."""
        applied = self._issued.applied_at(t_s)
        rest = {name: float(applied[INPUT[input_name]])
                for name, input_name in self._rest_inputs.items()}
        if not rest or self._last is None:
            return rest
        last_t_s, last_state = self._last
        state = self.predict(np.where(np.isfinite(last_state), last_state, 0.0),
                             last_t_s, t_s)
        values = {name: float(state[self._index[name]]) for name in rest}
        return values if all(math.isfinite(v) for v in values.values()) else rest

    def at(self, t_s: float, estimate: Estimate) -> np.ndarray:
        """The estimate's states and the internal ones at ``estimate.t_s``, predicted to
        ``max(t_s, estimate.t_s)`` plus the delay; NaN entries stay unpredicted."""
        source, target = self._gather(estimate.names)
        state = np.full(len(self._index), np.nan)
        state[target] = np.asarray(estimate.mean, dtype=float).reshape(-1)[source]
        for name, value in self._internal_states(estimate.t_s).items():
            state[self._index[name]] = value
        self._last = (estimate.t_s, state.copy())
        self._issued.forget_before(estimate.t_s)
        if np.isfinite(state).all():
            state = self.predict(state, estimate.t_s,
                                 max(t_s, estimate.t_s) + self._issued.delay_s)
        return state


class EstimatedStartMpc(MpcTracker):
    """An MPC whose model state is the estimate's (by name) plus the internal states it
    carries (:class:`StartingState`): the nonlinear MPCs and the LTV-MPC. A subclass calls
    :meth:`_init_start` after ``MpcTracker.__init__``."""

    def _init_start(self, who: str, state_names: tuple[str, ...],
                    estimated_names: tuple[str, ...], internal_rest_inputs: Mapping[str, str],
                    predict: ca.Function) -> None:
        self._starting = StartingState(who, state_names, estimated_names,
                                       internal_rest_inputs, predict, self._issued)

    def _forget(self) -> None:
        self._starting.reset()

    def _start(self, t_s: float, estimate: Estimate, reference: ReferencePath) -> Start:
        """The estimated start, with its caution: the factor on the steering-rate weight
        from the estimate's uncertainty across the car (:mod:`tracker.mpc.caution`,
        ``tracker.caution_lateral_sigma_m``)."""
        return Start(max(t_s, estimate.t_s) + self._issued.delay_s,
                     self._starting.at(t_s, estimate),
                     steer_rate_factor(estimate, self.config.caution_lateral_sigma_m))
