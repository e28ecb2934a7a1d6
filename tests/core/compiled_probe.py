"""A compiled CasADi function evaluated at many points through its C (tests/core's probes)."""

from __future__ import annotations

import ctypes
from pathlib import Path

import casadi as ca
import numpy as np

from cosim.core.compiled_function import CompiledFunction


def evaluated_at(library: Path, function: ca.Function, points: np.ndarray) -> np.ndarray:
    """Every output of ``function`` from ``library`` at each row of ``points`` (its inputs'
    numbers one after another), the outputs of a row side by side."""
    inputs = [np.zeros(function.nnz_in(i)) for i in range(function.n_in())]
    outputs = [np.zeros(function.nnz_out(i)) for i in range(function.n_out())]
    call = CompiledFunction(ctypes.CDLL(str(library)), function, inputs, outputs)
    rows = []
    for point in points:
        start = 0
        for values in inputs:
            values[:] = point[start:start + values.size]
            start += values.size
        call()
        rows.append(np.concatenate(outputs))
    return np.array(rows)
