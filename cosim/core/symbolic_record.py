"""A record's numbers as CasADi symbols: one function for every value of a belief.

A model written against a frozen dataclass of parameters (``record.mass_kg * ...``) builds a
CasADi expression with those numbers folded in as constants, so a new belief is a new
function (and a new compiled library). :func:`symbolic_twin` gives a copy of the record in
which every float field, nested records included, is an ``SX`` symbol: the same model code
then builds one function with the numbers as an input (:attr:`SymbolicRecord.vector`), and
the belief's numbers (:attr:`SymbolicRecord.values`) are what a caller passes for it.

The twin is made without calling the record's ``__init__`` (its validation compares
numbers, which a symbol cannot be), so only arithmetic on the fields is possible: a model
that branches on a number's value (``if record.x > 0``) raises CasADi's error when built.
Fields of other types (strings naming a law, integers counting) stay as they are: they
choose the structure of the function, not a number in it.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import casadi as ca
import numpy as np

Record = TypeVar("Record")


@dataclass(frozen=True)
class SymbolicRecord(Generic[Record]):
    """A record whose float fields are symbols, with the names and values behind them."""

    twin: Record
    """The record with each float field replaced by its symbol."""
    names: tuple[str, ...]
    """Each symbol's dotted field path (``roll.frequency_hz``), in :attr:`vector` order."""
    values: np.ndarray
    """The record's own numbers, in :attr:`vector` order."""
    vector: ca.SX
    """The symbols as one column (the function input that takes :attr:`values`)."""


def symbolic_twin(record: Record, prefix: str = "") -> SymbolicRecord[Record]:
    """The twin of the dataclass ``record`` with its float fields (recursively) symbolic;
    ``prefix`` starts every symbol's name."""
    names: list[str] = []
    values: list[float] = []
    symbols: list[ca.SX] = []
    twin = _twin(record, prefix, names, values, symbols)
    return SymbolicRecord(twin, tuple(names), np.array(values, dtype=float),
                          ca.vertcat(*symbols) if symbols else ca.SX(0, 1))


def _twin(record: Any, prefix: str, names: list[str], values: list[float],
          symbols: list[ca.SX]) -> Any:
    if not dataclasses.is_dataclass(record) or isinstance(record, type):
        raise TypeError(f"{type(record).__name__}: expected a dataclass instance")
    twin = copy.copy(record)
    for field in dataclasses.fields(record):
        value = getattr(record, field.name)
        path = f"{prefix}{field.name}"
        if isinstance(value, float):
            symbol = ca.SX.sym(path)
            names.append(path)
            values.append(value)
            symbols.append(symbol)
            object.__setattr__(twin, field.name, symbol)
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            object.__setattr__(twin, field.name,
                               _twin(value, f"{path}.", names, values, symbols))
    return twin
