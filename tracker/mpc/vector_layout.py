"""Named blocks of one flat vector: how the MPCs lay out variables, parameters, constraints.

CasADi solvers take one vector of decision variables, one of parameters and one of
constraints. Each tracker declares the blocks of each vector by name and size once;
:class:`VectorLayout` then cuts a symbolic vector into its blocks (to build the problem)
and packs numeric blocks into one vector (to call it), so no code indexes by hand.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

import casadi as ca
import numpy as np


class VectorLayout:
    """Named blocks of a flat vector, in declaration order.

    Args:
      sizes: ``((name, size), ...)``, the blocks in vector order.
    """

    def __init__(self, sizes: tuple[tuple[str, int], ...]) -> None:
        slices: dict[str, slice] = {}
        start = 0
        for name, size in sizes:
            slices[name] = slice(start, start + size)
            start += size
        self.slices: Mapping[str, slice] = MappingProxyType(slices)
        self.size = start

    def split(self, vector: ca.SX | ca.MX) -> dict[str, ca.SX | ca.MX]:
        """Symbolic blocks of ``vector`` by name."""
        return {name: vector[s] for name, s in self.slices.items()}

    def pack(self, blocks: Mapping[str, np.ndarray | float]) -> np.ndarray:
        """One flat vector from every named block (each must have its declared size)."""
        if set(blocks) != set(self.slices):
            raise ValueError(f"expected blocks {sorted(self.slices)}, got {sorted(blocks)}")
        out = np.empty(self.size)
        for name, s in self.slices.items():
            out[s] = np.asarray(blocks[name], dtype=float).ravel()
        return out
