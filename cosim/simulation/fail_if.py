"""``cosim run --fail-if 'cte_max_m>0.3'``: conditions on a run's metrics for scripts and CI.

A condition may also be an STL formula over the run's signals
(:mod:`cosim.simulation.requirements`): ``--fail-if 'eventually (abs(cte_m) > 0.3)'`` fails
the run when the formula holds; ``cosim run --require 'always (abs(cte_m) <= 0.3)'`` when it
is violated. Either adds a requirement to the run, whose robustness is a metric.

A condition is ``METRIC OP VALUE`` with OP one of ``<``, ``<=``, ``>``, ``>=``, ``==``,
``!=``. Every condition is parsed and checked before the run starts, so a typo costs no
simulation (one line, exit code 2, the closest metric suggested):

- METRIC must be a metric cosim knows (:func:`metric_kind`, from the registry
  :mod:`cosim.simulation.metric_keys`): a number (``cte_max_m``), true or false
  (``completed``) or a word (``outcome``);
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
from dataclasses import dataclass, replace
from typing import Any

from cosim.core.exceptions import ConfigError
from cosim.core.yaml_io import shown
from cosim.simulation.metric_keys import METRICS, metric_key
from cosim.simulation.requirements import TEMPORAL, check_formula

_OPERATORS: dict[str, Callable[[Any, Any], bool]] = {
    "<=": operator.le, ">=": operator.ge, "==": operator.eq, "!=": operator.ne,
    "<": operator.lt, ">": operator.gt,
}
_PATTERN = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(<=|>=|==|!=|<|>)\s*(\S.*?)\s*$")
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")

NUMBER, FLAG, WORD = "number", "flag", "word"
"""The kinds of metric a condition can test."""


def metric_kind(name: str) -> str | None:
    """``number``, ``flag`` or ``word`` for a metric cosim produces (a key of
    :mod:`cosim.simulation.metric_keys`, families included); None if unknown."""
    row = metric_key(name)
    if row is None:
        return None
    return {"bool": FLAG, "text": WORD}.get(row.unit, NUMBER)


def known_metrics() -> tuple[str, ...]:
    """Every fixed metric name (the families aside), for suggestions."""
    return tuple(row.name for row in METRICS if not row.is_family)


@dataclass(frozen=True)
class Condition:
    """One ``--fail-if`` condition."""

    text: str
    metric: str
    op: str
    value: float | bool | str
    option: str = "--fail-if"
    """The option that gave it: ``--fail-if``, or ``--require`` (a requirement that fails
    the run when violated)."""
    formula: bool = False
    """An STL formula (:mod:`cosim.simulation.requirements`): it tests the robustness metric
    of the requirement the run adds for it (:func:`bind_formulas`)."""

    def failure(self, metrics: dict[str, Any]) -> str:
        """The line that says why this condition fails the run."""
        value = metrics.get(self.metric)
        if value is None:
            return f"{self.option} {self.text!r}: this run has no metric {self.metric!r}"
        if self.option == "--require":
            return f"{self.option} {self.text!r} is violated (robustness {value:.4g})"
        if self.formula:  # its requirement is the negation: minus its robustness
            return f"{self.option} {self.text!r} holds (robustness {-value:.4g})"
        return f"{self.option} {self.text!r} holds ({self.metric} = {value:.4g})" \
            if isinstance(value, (int, float)) and not isinstance(value, bool) else \
            f"{self.option} {self.text!r} holds ({self.metric} = {value})"

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
    if (match is None or metric_kind(match.group(1)) is None) and TEMPORAL.search(text):
        check_formula(text, "--fail-if")  # an STL formula: the run fails if it holds
        return Condition(text, "", ">=", 0.0, formula=True)
    if match is None:
        raise _error(text, "expected METRIC OP VALUE with OP one of <, <=, >, >=, ==, != "
                     "(e.g. 'cte_max_m>0.3'), or an STL formula (e.g. "
                     "'eventually (abs(cte_m) > 0.3)')")
    metric, op, raw = match.groups()
    kind = metric_kind(metric)
    if kind is None:
        raise _error(text, f"unknown metric {metric!r}{_closest(metric, known_metrics())}: "
                     "expected a metric of `cosim inspect --json` (e.g. cte_max_m)")
    if kind == NUMBER:
        if not _NUMBER.match(raw) or not math.isfinite(float(raw)):
            hint = _unit_hint(raw, metric_key(metric).unit)  # type: ignore[union-attr]
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
    words = metric_key(metric).values  # type: ignore[union-attr]
    if words and raw not in words:
        raise _error(text, f"{shown(raw)}{_closest(raw, words)}: expected one of "
                     f"{', '.join(words)} for {metric}")
    return Condition(text, metric, op, raw)


UNIT_FACTORS: dict[str, dict[str, float]] = {
    "m": {"mm": 1e-3, "cm": 1e-2, "m": 1.0, "km": 1e3},
    "rad": {"rad": 1.0, "deg": math.pi / 180.0, "mrad": 1e-3},
    "s": {"ms": 1e-3, "s": 1.0, "min": 60.0},
    "ms": {"ms": 1.0, "s": 1e3, "us": 1e-3},
    "m/s": {"m/s": 1.0, "mps": 1.0, "km/h": 1.0 / 3.6, "kph": 1.0 / 3.6},
    "m/s^2": {"m/s^2": 1.0, "mps2": 1.0, "g": 9.80665},
    "rad/s": {"rad/s": 1.0, "radps": 1.0, "deg/s": math.pi / 180.0},
}
"""Units a ``--fail-if`` value may have been typed in, per metric unit, with the factor to
the metric's unit (for the hint only: the value itself must be a plain number)."""


def _unit_hint(raw: str, unit: str) -> str:
    """`` (in m: 0.3)`` for ``30cm`` against a metric in metres: the number to type,
    converted; `` (a plain number in m)`` for a unit it cannot convert."""
    match = re.match(r"^([+-]?[\d.]+(?:[eE][+-]?\d+)?)\s*([A-Za-z%/^0-9]+)$", raw)
    if match is None:
        return ""
    number, typed = match.groups()
    factor = UNIT_FACTORS.get(unit, {}).get(typed)
    try:
        value = float(number)
    except ValueError:
        return ""
    if factor is None:
        return f" (a plain number in {unit})" if unit not in ("1", "count") else ""
    return f" (in {unit}: {value * factor:.6g})"


def parse_conditions(texts: Sequence[str]) -> list[Condition]:
    """Parse every ``--fail-if`` text; a malformed one is a ConfigError naming it."""
    return [parse_condition(text) for text in texts]


def bind_formulas(conditions: Sequence[Condition], requires: Sequence[str],
                  first_index: int) -> list[Condition]:
    """The conditions of a run whose requirements from ``first_index`` on are ``requires``
    then the negation of each ``--fail-if`` formula (:func:`formula_requirements`), in
    order: each fails the run when its requirement's robustness is below zero."""
    bound = [Condition(text, f"stl_robustness_{first_index + i}", "<", 0.0,
                       option="--require", formula=True) for i, text in enumerate(requires)]
    index = first_index + len(requires)
    for condition in conditions:
        if condition.formula:
            bound.append(replace(condition, metric=f"stl_robustness_{index}", op="<"))
            index += 1
        else:
            bound.append(condition)
    return bound


def formula_requirements(conditions: Sequence[Condition], requires: Sequence[str]) -> list[str]:
    """The requirements a run adds for its options: each ``--require`` formula, then for
    each ``--fail-if`` formula its negation (the run must not let it hold), so that every
    requirement is one the run should satisfy and ``stl_robustness`` is their worst."""
    return [*requires, *(f"not ({c.text})" for c in conditions if c.formula)]
