"""The vehicle model as the shared NMPC (:mod:`tracker.mpc.nmpc`) needs it.

A tracker is an :class:`NmpcModel` plus a :class:`tracker.config.TrackerConfig`: the model's
discrete step ``F`` and continuous prediction ``P`` as CasADi functions, which of its
states an estimate provides and which the tracker carries itself, and its optional soft
limits (the tyres' linear range, the friction ellipse).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import casadi as ca

from cosim.core.exceptions import ConfigError
from tracker.mpc.fallback import INPUT_NAMES

REQUIRED_STATE_NAMES: tuple[str, ...] = ("x_m", "y_m", "yaw_rad", "vx_mps")
"""States the cost and the safe stop read: CoG position (world frame), yaw, forward speed."""


@dataclass(frozen=True)
class NmpcModel:
    """A vehicle model as the shared NMPC needs it.

    ``step`` is ``F(state, inputs) -> next_state`` over one stage of ``dt_s``; ``predict``
    is ``P(state, inputs, duration_s) -> state`` for a variable duration (latency, elapsed
    time); both hold the inputs over the interval. ``estimated_state_names`` are read from
    the :class:`~cosim.core.records.Estimate` by name; every other state is internal and
    ``internal_rest_inputs`` names the input each one rests at (its value when nothing
    else is known). ``unmodelled_lag_s`` is the actuator lag the model lacks, added to the
    prediction over the latency.
    """

    name: str
    state_names: tuple[str, ...]
    estimated_state_names: tuple[str, ...]
    step: ca.Function
    predict: ca.Function
    dt_s: float
    unmodelled_lag_s: float = 0.0
    understeer_gradient_radpmps2: float = 0.0
    """K of the model's steady turn, ``delta = atan(L kappa) + K v^2 kappa`` (0: neutral)."""
    steady_grip_mps2: float | None = None
    """``mu g`` of a model whose tyres saturate: its steady turn needs
    ``atan(L kappa) + K mu g atanh(v^2 kappa / (mu g))``, (S4) of
    :mod:`tracker.models.dynamic_bicycle`; None: linear tyres, the line above."""
    internal_rest_inputs: Mapping[str, str] = field(default_factory=dict)
    input_names: tuple[str, ...] = INPUT_NAMES
    limits: ca.Function | None = None
    """``h(state) -> limited quantities`` (e.g. tyre slip angles), or None."""
    limit_names: tuple[str, ...] = ()
    """Names of ``h``'s outputs, in order (units in the names)."""
    limit_bounds: tuple[float, ...] = ()
    """``h_max`` for each of ``h``'s outputs: the soft bound ``|h| <= h_max``."""
    stage_limits: ca.Function | None = None
    """``g(state, inputs) -> limited quantities`` of a stage's start node and its inputs
    (e.g. the tyres' friction usage, :mod:`tracker.models.tyre_limits`), or None."""
    stage_limit_names: tuple[str, ...] = ()
    """Names of ``g``'s outputs, in order."""
    stage_limit_bounds: tuple[float, ...] = ()
    """``g_max`` for each of ``g``'s outputs: the soft bound ``|g| <= g_max``."""
    belief: tuple[float, ...] = ()
    """The belief's numbers as the NLP takes them, a parameter of every solve (so the NLP,
    and its compiled code, is the same for every belief of the same shape); empty for a
    model whose functions carry their numbers. With a belief, ``belief_step`` replaces
    ``step`` in the NLP and ``belief_limits``/``belief_stage_limits`` replace the limits
    and their bounds; at ``belief`` each computes what the plain function does."""
    belief_step: ca.Function | None = None
    """``F(state, inputs, belief) -> next_state``."""
    belief_limits: ca.Function | None = None
    """``(state, belief) -> (h, h_max)``: the limits and their bounds."""
    belief_stage_limits: ca.Function | None = None
    """``(state, inputs, belief) -> (g, g_max)``: the stage limits and their bounds."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "internal_rest_inputs",
                           MappingProxyType(dict(self.internal_rest_inputs)))
        if self.input_names != INPUT_NAMES:
            raise ConfigError(f"model {self.name}: inputs {self.input_names}, expected "
                              f"{INPUT_NAMES}")
        missing = [n for n in REQUIRED_STATE_NAMES if n not in self.state_names]
        if missing:
            raise ConfigError(f"model {self.name}: expected states {missing}")
        internal = set(self.state_names) - set(self.estimated_state_names)
        if set(self.estimated_state_names) - set(self.state_names):
            raise ConfigError(f"model {self.name}: estimated states must be model states")
        if internal != set(self.internal_rest_inputs):
            raise ConfigError(f"model {self.name}: internal states {sorted(internal)} need "
                              "a rest input each (internal_rest_inputs)")
        if set(self.internal_rest_inputs.values()) - set(INPUT_NAMES):
            raise ConfigError(f"model {self.name}: rest inputs must be among {INPUT_NAMES}")
        if not (math.isfinite(self.unmodelled_lag_s) and self.unmodelled_lag_s >= 0.0):
            raise ConfigError(f"model {self.name}: unmodelled_lag_s = "
                              f"{self.unmodelled_lag_s!r}: expected a number >= 0")
        n_limits = 0 if self.limits is None else self.limits.size1_out(0)
        if len(self.limit_names) != n_limits or len(self.limit_bounds) != n_limits:
            raise ConfigError(f"model {self.name}: expected {n_limits} limit names and bounds")
        if not all(math.isfinite(b) and b > 0.0 for b in self.limit_bounds):
            raise ConfigError(f"model {self.name}: limit bounds {self.limit_bounds}: expected "
                              "positive numbers")
        if self.limits is not None and (self.limits.n_in() != 1
                                        or self.limits.size1_in(0) != len(self.state_names)):
            raise ConfigError(f"model {self.name}: limits must be a function of the state")
        n_stage = 0 if self.stage_limits is None else self.stage_limits.size1_out(0)
        if (len(self.stage_limit_names) != n_stage
                or len(self.stage_limit_bounds) != n_stage):
            raise ConfigError(f"model {self.name}: expected {n_stage} stage limit names and "
                              "bounds")
        if not all(math.isfinite(b) and b > 0.0 for b in self.stage_limit_bounds):
            raise ConfigError(f"model {self.name}: stage limit bounds "
                              f"{self.stage_limit_bounds}: expected positive numbers")
        if self.stage_limits is not None and (
                self.stage_limits.n_in() != 2
                or self.stage_limits.size1_in(0) != len(self.state_names)
                or self.stage_limits.size1_in(1) != len(self.input_names)):
            raise ConfigError(f"model {self.name}: stage limits must be a function of the "
                              "state and the inputs")
        n_x, n_u = len(self.state_names), len(self.input_names)
        for function, n_in in ((self.step, 2), (self.predict, 3)):
            if (function.n_in() != n_in or function.size1_in(0) != n_x
                    or function.size1_in(1) != n_u or function.size1_out(0) != n_x):
                raise ConfigError(f"model {self.name}: {function.name()} does not match "
                                  f"{n_x} states and {n_u} inputs")
        self._check_belief()

    def _check_belief(self) -> None:
        n_b = len(self.belief)
        given = {"belief_step": self.belief_step, "belief_limits": self.belief_limits,
                 "belief_stage_limits": self.belief_stage_limits}
        if not n_b:
            if any(function is not None for function in given.values()):
                raise ConfigError(f"model {self.name}: belief functions need a belief")
            return
        if self.belief_step is None:
            raise ConfigError(f"model {self.name}: a belief needs belief_step")
        for label, function, plain in (("belief_limits", self.belief_limits, self.limits),
                                       ("belief_stage_limits", self.belief_stage_limits,
                                        self.stage_limits)):
            if (function is None) != (plain is None):
                raise ConfigError(f"model {self.name}: {label} must be given exactly when "
                                  "the plain limits are")
        for label, function in given.items():
            if function is not None and function.size1_in(function.n_in() - 1) != n_b:
                raise ConfigError(f"model {self.name}: {label} takes a belief of "
                                  f"{function.size1_in(function.n_in() - 1)} numbers, "
                                  f"expected {n_b}")

    def nlp_step(self, state: ca.SX, inputs: ca.SX, belief: ca.SX) -> ca.SX:
        """The NLP's step from ``state``: ``belief_step`` with the belief parameter, else
        ``step``."""
        if self.belief_step is not None:
            return self.belief_step(state, inputs, belief)
        return self.step(state, inputs)

    def nlp_limits(self, state: ca.SX, belief: ca.SX) -> tuple[ca.SX, ca.SX] | None:
        """``(h, h_max)`` at ``state`` as the NLP takes them, or None without limits."""
        if self.belief_limits is not None:
            return self.belief_limits(state, belief)
        if self.limits is None:
            return None
        return self.limits(state), ca.DM(list(self.limit_bounds))

    def nlp_stage_limits(self, state: ca.SX, inputs: ca.SX,
                         belief: ca.SX) -> tuple[ca.SX, ca.SX] | None:
        """``(g, g_max)`` of a stage as the NLP takes them, or None without stage limits."""
        if self.belief_stage_limits is not None:
            return self.belief_stage_limits(state, inputs, belief)
        if self.stage_limits is None:
            return None
        return self.stage_limits(state, inputs), ca.DM(list(self.stage_limit_bounds))
