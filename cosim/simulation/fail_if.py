"""``cosim run --fail-if 'cte_max_m>0.3'``: conditions on a run's metrics for scripts and CI.

A condition is ``METRIC OP VALUE`` with OP one of ``<``, ``<=``, ``>``, ``>=``, ``==``,
``!=``; VALUE is a number, ``true``/``false`` or a word (for ``outcome``). The metric must
be one every run has (:data:`cosim.simulation.metrics.METRIC_KEYS`, ``outcome``) or one the
run produced; a metric the run lacks, or a non-finite value, makes the condition hold (a
check that cannot be made is not a pass).
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from cosim.core.exceptions import ConfigError
from cosim.core.yaml_io import shown

_OPERATORS: dict[str, Callable[[Any, Any], bool]] = {
    "<=": operator.le, ">=": operator.ge, "==": operator.eq, "!=": operator.ne,
    "<": operator.lt, ">": operator.gt,
}
_PATTERN = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(<=|>=|==|!=|<|>)\s*(\S.*?)\s*$")


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
        if isinstance(self.value, str) or isinstance(actual, str):
            if self.op not in ("==", "!="):
                return True
            return _OPERATORS[self.op](str(actual), str(self.value))
        if isinstance(actual, float) and not math.isfinite(actual):
            return True
        return bool(_OPERATORS[self.op](actual, self.value))


def _value(raw: str) -> float | bool | str:
    if raw in ("true", "false"):
        return raw == "true"
    try:
        number = float(raw)
    except ValueError:
        return raw
    if not math.isfinite(number):
        raise ValueError(raw)
    return number


def parse_conditions(texts: Sequence[str]) -> list[Condition]:
    """Parse every ``--fail-if`` text; a malformed one is a ConfigError naming it."""
    conditions = []
    for text in texts:
        match = _PATTERN.match(text)
        try:
            if match is None:
                raise ValueError(text)
            metric, op, raw = match.groups()
            conditions.append(Condition(text, metric, op, _value(raw)))
        except ValueError:
            raise ConfigError(f"--fail-if {shown(text)}: expected METRIC OP VALUE with OP one "
                              "of <, <=, >, >=, ==, != (e.g. 'cte_max_m>0.3')") from None
    return conditions
