"""Summary statistics kept in constant memory while a run goes.

A run of an hour logs 360 000 samples per signal at 100 Hz; keeping each one as a Python
float in a list cost about 70 KB of memory per simulated second over all the metrics. The
metrics need only counts, sums of squares, extremes and the last value, which
:class:`RunningStats` keeps in a few numbers. Percentiles (solve times) need every sample:
:class:`Samples` keeps them as packed doubles (8 bytes each, 20 Hz: 0.6 MB an hour).
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass

import numpy as np


@dataclass
class RunningStats:
    """Count, mean, RMS, extremes and the last value of a stream of numbers.

    Non-finite samples are counted in ``nonfinite`` and left out of the statistics (a
    diverging run's NaNs must not hide the maximum that came before).
    """

    count: int = 0
    nonfinite: int = 0
    total: float = 0.0
    total_sq: float = 0.0
    low: float = math.inf
    high: float = -math.inf
    last: float = math.nan

    def add(self, value: float) -> None:
        self.last = value
        if not math.isfinite(value):
            self.nonfinite += 1
            return
        self.count += 1
        self.total += value
        self.total_sq += value * value
        self.low = min(self.low, value)
        self.high = max(self.high, value)

    @property
    def mean(self) -> float:
        return self.total / self.count if self.count else math.nan

    @property
    def rms(self) -> float:
        return math.sqrt(self.total_sq / self.count) if self.count else math.nan

    @property
    def max_abs(self) -> float:
        return max(abs(self.low), abs(self.high)) if self.count else math.nan

    @property
    def minimum(self) -> float:
        return self.low if self.count else math.nan

    @property
    def maximum(self) -> float:
        return self.high if self.count else math.nan


class Samples:
    """Every sample of a stream, packed as doubles, for percentiles."""

    def __init__(self) -> None:
        self._values = array("d")

    def add(self, value: float) -> None:
        self._values.append(value)

    def __len__(self) -> int:
        return len(self._values)

    def as_array(self) -> np.ndarray:
        return np.frombuffer(self._values, dtype=float).copy()
