"""Whether the unit an FMU declares for a variable agrees with the unit its name implies.

A unit is compared by its SI base-unit exponents (FMI 2.0.4 section 2.2.2 and FMI 3.0
section 2.4.3: ``<BaseUnit kg= m= s= A= K= mol= cd= rad= factor= offset=>``, the value in
base units being ``factor * value + offset``). The FMU's unit agrees when either

- its unit definition carries a ``BaseUnit`` with the expected exponents, or
- its name, read as a Modelica unit expression (``m/s2``, ``m.s-2``, ``m/s^2``, ``rad/s``,
  ``1/m``, ``m-1``; Modelica Language Specification 3.6, section 19.1), has them;

and never when its ``BaseUnit`` has a factor other than 1 or an offset (``deg``, ``km/h``,
``mm``: the values would be scaled). A variable without a unit is not checked: FMI makes
units optional, and cosim says in its documentation what it sends.
"""

from __future__ import annotations

import re
from collections import Counter
from typing import Any

BASE_SYMBOLS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
"""The base units of FMI's ``BaseUnit`` element."""

COSIM_UNITS: dict[str, dict[str, int]] = {
    "-": {},
    "m": {"m": 1},
    "s": {"s": 1},
    "rad": {"rad": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s^2": {"m": 1, "s": -2},
    "rad/s": {"rad": 1, "s": -1},
    "1/m": {"m": -1},
}
"""Base-unit exponents of the units cosim's signals carry."""

_FACTOR = re.compile(r"^([A-Za-z]+)\^?(-?\d+)?$")


def parse_unit(text: str) -> dict[str, int] | None:
    """Base-unit exponents of a unit expression (``m/s2`` -> ``{m: 1, s: -2}``), or None
    when it is not made of base units alone (``deg``, ``km/h``)."""
    numerator, _, denominator = text.strip().partition("/")
    exponents: Counter[str] = Counter()
    for part, sign in ((numerator, 1), (denominator, -1)):
        for factor in re.split(r"[.*\s]+", part.strip()):
            if factor in ("", "1"):
                continue
            match = _FACTOR.match(factor)
            if match is None or match[1] not in BASE_SYMBOLS:
                return None
            exponents[match[1]] += sign * int(match[2] or 1)
    return {k: v for k, v in exponents.items() if v}


def _base_unit(definition: Any) -> tuple[dict[str, int], float, float] | None:
    """Exponents, factor and offset of an fmpy ``Unit`` definition's ``BaseUnit``."""
    base = getattr(definition, "baseUnit", None)
    if base is None:
        return None
    exponents = {symbol: int(getattr(base, symbol)) for symbol in BASE_SYMBOLS
                 if getattr(base, symbol)}
    return exponents, float(base.factor), float(base.offset)


def unit_disagrees(declared: str | None, expected: str, definitions: dict[str, Any]) -> str:
    """Why the FMU's ``declared`` unit disagrees with cosim's ``expected`` one ("" when it
    agrees or none is declared); ``definitions`` are the FMU's unit definitions by name."""
    if not declared:
        return ""
    wanted = COSIM_UNITS[expected]
    base = _base_unit(definitions.get(declared))
    if base is not None:
        exponents, factor, offset = base
        if factor != 1.0 or offset != 0.0:
            return (f"unit {declared!r} is {factor:g} x base units"
                    + (f" + {offset:g}" if offset else "") + f": expected {expected}")
        if exponents == wanted:
            return ""
    if parse_unit(declared) == wanted:
        return ""
    return f"unit {declared!r}: expected {expected}"
