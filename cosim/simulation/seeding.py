"""One run seed, many independent random streams: one per component, keyed by its name."""

from __future__ import annotations

import zlib

import numpy as np


def component_rng(seed: int, component: str) -> np.random.Generator:
    """The generator of one component, derived from the run's seed and the component's name.

    Keyed by name (CRC-32), not by position, so adding a sensor leaves every other
    component's random stream unchanged.
    """
    return np.random.default_rng([seed, zlib.crc32(component.encode())])
