"""Summary statistics kept in constant memory while a run goes.

A run of an hour logs 360 000 samples per signal at 100 Hz; keeping each one as a Python
float in a list cost about 70 KB of memory per simulated second over all the metrics. The
metrics need only counts, sums of squares, extremes and the last value, which
:class:`RunningStats` keeps in a few numbers. Percentiles (solve times) need every sample:
:class:`Samples` keeps them as packed doubles (8 bytes each, 20 Hz: 0.6 MB an hour).

A loop that updates a dozen statistics per sample pays Python's call overhead a dozen times;
:class:`SampleBlock` instead writes each sample's row of values into a preallocated block
(one assignment) and reduces the block into the statistics with numpy when it fills: the
same figures (sums in numpy's pairwise order, so equal to a sample-by-sample sum to about
1e-15 relative), in constant memory.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Callable, Sequence
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

    def merge(self, values: np.ndarray) -> None:
        """Add every value of the 1-D array ``values``, in order (as :meth:`add` would)."""
        if not values.size:
            return
        self.last = float(values[-1])
        finite = values[np.isfinite(values)]
        self.nonfinite += values.size - finite.size
        if not finite.size:
            return
        self.count += finite.size
        self.total += float(finite.sum())
        self.total_sq += float(finite @ finite)
        self.low = min(self.low, float(finite.min()))
        self.high = max(self.high, float(finite.max()))

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


class SampleBlock:
    """Rows of samples, a fixed number of columns each, written into a preallocated block and
    handed to ``reduce`` (a function of the filled rows, a 2-D array) whenever the block fills
    and on :meth:`flush`: per-sample statistics at the cost of one array assignment a sample.
    The rows are reduced in fixed groups (``rows`` at a time), so sums round the same way
    however often a reader looks at :meth:`pending`.

    ``reduce`` must not keep the array it is given (the block is written over afterwards).
    """

    def __init__(self, columns: int, reduce: Callable[[np.ndarray], None],
                 rows: int = 1024) -> None:
        self._rows = np.empty((rows, columns))
        self._filled = 0
        self._reduce = reduce

    def add(self, row: Sequence[float] | np.ndarray) -> None:
        """Append one sample's ``columns`` values."""
        self.next_row()[:] = row

    def next_row(self) -> np.ndarray:
        """The next sample's row (a view into the block) for the caller to fill in whole
        before any other call: it counts as written."""
        if self._filled == len(self._rows):
            self.flush()
        row = self._rows[self._filled]
        self._filled += 1
        return row

    def pending(self) -> np.ndarray:
        """The rows written since the last reduction (a view: read it before the next
        :meth:`add`)."""
        return self._rows[:self._filled]

    def flush(self) -> None:
        """Reduce the rows written since the last flush, and start the block afresh."""
        if self._filled:
            filled, self._filled = self._filled, 0
            self._reduce(self._rows[:filled])
