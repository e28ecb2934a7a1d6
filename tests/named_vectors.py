"""Test helper: a model vector from named values (never by bare index)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


def named_vector(index: Mapping[str, int], **values: float) -> np.ndarray:
    """A vector over ``index``'s names, zero except the named ``values``."""
    vector = np.zeros(len(index))
    for name, value in values.items():
        vector[index[name]] = value
    return vector
