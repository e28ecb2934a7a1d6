"""``cosim run --fail-if 'cte_max_m>0.3'``: conditions on a run's metrics for scripts and CI.

A condition is ``METRIC OP VALUE`` with OP one of ``<``, ``<=``, ``>``, ``>=``, ``==``,
``!=``. Every condition is parsed and checked before the run starts, so a typo costs no
simulation (one line, exit code 2, the closest metric suggested):

- METRIC must be a metric cosim knows (:func:`metric_kind`): a number (``cte_max_m``), true
  or false (``completed``) or a word (``outcome``);
- VALUE must fit the metric: a plain number for a number (no unit: ``0.3``, not ``0.3m``),
  ``true`` or ``false`` for a flag, one of the metric's words for a word;
- OP must fit too: a flag or a word is compared with ``==`` or ``!=`` only.

After the run, a known metric the run did not produce (``gap_min_m`` without traffic), or a
non-finite value, makes the condition hold: a check that cannot be made is not a pass.
"""

from __future__ import annotations

import difflib
import math
import operator
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from cosim.core.exceptions import ConfigError
from cosim.core.yaml_io import shown
from cosim.simulation.metrics import METRIC_KEYS, REJECTION_CAUSES
from cosim.simulation.outcome import OUTCOMES, SEVERITY

_OPERATORS: dict[str, Callable[[Any, Any], bool]] = {
    "<=": operator.le, ">=": operator.ge, "==": operator.eq, "!=": operator.ne,
    "<": operator.lt, ">": operator.gt,
}
_PATTERN = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(<=|>=|==|!=|<|>)\s*(\S.*?)\s*$")
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")

NUMBER, FLAG, WORD = "number", "flag", "word"
"""The kinds of metric a condition can test."""

FLAG_METRICS = ("completed", "safe_gap_ok", "esc_gains_settled")
WORD_METRICS: dict[str, tuple[str, ...] | None] = {
    "outcome": OUTCOMES, "abort_reason": None, "acc_targets": None}
"""Metrics whose value is a word: the words allowed (None: any text)."""

NUMBER_METRICS = (
    *(k for k in METRIC_KEYS if k not in FLAG_METRICS),
    "lat_accel_max_mps2", "jerk_rms_mps3", "lat_jerk_rms_mps3", "speed_reduced_steps",
    "events", "faults_injected", "rejected_measurements", *REJECTION_CAUSES,
    "channels_gated", "estimator_surprises", "gates_hit", "track_limit_exceedances",
    "gap_min_m", "time_gap_min_s", "ttc_min_s", "safe_gap_margin_min_m",
    "acc_speed_err_rms_mps", "acc_speed_err_final_mps", "acc_set_speed_t_s",
    "acc_gap_mode_t_s", "acc_gap_mode_s", "acc_objective_mean", "acc_objective_gap_mean",
    "acc_objective_steady_mean", "acc_objective_final_mean", "acc_k_v", "acc_k_x",
    "acc_k_vrel", "acc_k_v_drift_pct", "acc_k_x_drift_pct", "acc_k_vrel_drift_pct",
    "acc_target_changes", "esc_gain_drift_pct",
    "steady_speed_mps", "steady_steer_rad", "steady_yaw_rate_radps", "steady_ay_mps2",
    "steady_radius_m", "steady_yaw_rate_gain_1ps", "yaw_rate_response_time_s",
    "yaw_rate_overshoot", "ay_max_mps2",
    *(f"{kind}_t_s" for kind in SEVERITY),
)
"""Numeric metrics of the runner, the course, traffic and the manoeuvres."""

FAMILIES: tuple[tuple[re.Pattern[str], str], ...] = (
    (re.compile(r"^nis_(dof_)?[a-z][a-z0-9_]*$"), NUMBER),   # per sensor: nis_gnss
    (re.compile(r"^gate_\d+_passed$"), FLAG),                # ISO 3888-1 gates
)
"""Metric names made per sensor or per gate."""


def metric_kind(name: str) -> str | None:
    """``number``, ``flag`` or ``word`` for a metric cosim produces; None if unknown."""
    if name in FLAG_METRICS:
        return FLAG
    if name in WORD_METRICS:
        return WORD
    if name in NUMBER_METRICS:
        return NUMBER
    return next((kind for pattern, kind in FAMILIES if pattern.match(name)), None)


def known_metrics() -> tuple[str, ...]:
    """Every fixed metric name (the families aside), for suggestions."""
    return (*NUMBER_METRICS, *FLAG_METRICS, *WORD_METRICS)


@dataclass(frozen=True)
class Condition:
    """One ``--fail-if`` condition."""

    text: str
    metric: str
    op: str
    value: float | bool | str

    def holds(self, metrics: dict[str, Any]) -> bool:
        actual = metrics.get(self.metric)
        if actual is None:
            return True
        if isinstance(self.value, str):
            return bool(_OPERATORS[self.op](str(actual), self.value))
        if isinstance(self.value, bool):
            if not isinstance(actual, bool):
                return True
            return bool(_OPERATORS[self.op](actual, self.value))
        if isinstance(actual, (bool, str)) or not math.isfinite(float(actual)):
            return True
        return bool(_OPERATORS[self.op](float(actual), self.value))


def _error(text: str, why: str) -> ConfigError:
    return ConfigError(f"--fail-if {shown(text)}: {why}")


def _closest(word: str, choices: Sequence[str]) -> str:
    close = difflib.get_close_matches(word, choices, n=1, cutoff=0.5)
    return f" (did you mean {close[0]!r}?)" if close else ""


def parse_condition(text: str) -> Condition:
    """One ``--fail-if`` text as a :class:`Condition`, checked (module docstring)."""
    match = _PATTERN.match(text)
    if match is None:
        raise _error(text, "expected METRIC OP VALUE with OP one of <, <=, >, >=, ==, != "
                     "(e.g. 'cte_max_m>0.3')")
    metric, op, raw = match.groups()
    kind = metric_kind(metric)
    if kind is None:
        raise _error(text, f"unknown metric {metric!r}{_closest(metric, known_metrics())}: "
                     "expected a metric of `cosim inspect --json` (e.g. cte_max_m)")
    if kind == NUMBER:
        if not _NUMBER.match(raw) or not math.isfinite(float(raw)):
            unit = re.match(r"^([+-]?[\d.]+(?:[eE][+-]?\d+)?)\s*[A-Za-z%/]+$", raw)
            hint = f" (without a unit: {unit.group(1)})" if unit else ""
            raise _error(text, f"{shown(raw)} is not a number{hint}: expected {metric} "
                         f"{op} a finite number in the metric's own unit")
        return Condition(text, metric, op, float(raw))
    if op not in ("==", "!="):
        raise _error(text, f"{metric} is {'true or false' if kind == FLAG else 'a word'}: "
                     "expected == or != (not an order)")
    if kind == FLAG:
        if raw not in ("true", "false"):
            raise _error(text, f"{shown(raw)}: expected true or false for {metric}")
        return Condition(text, metric, op, raw == "true")
    words = WORD_METRICS[metric]
    if words is not None and raw not in words:
        raise _error(text, f"{shown(raw)}{_closest(raw, words)}: expected one of "
                     f"{', '.join(words)} for {metric}")
    return Condition(text, metric, op, raw)


def parse_conditions(texts: Sequence[str]) -> list[Condition]:
    """Parse every ``--fail-if`` text; a malformed one is a ConfigError naming it."""
    return [parse_condition(text) for text in texts]
