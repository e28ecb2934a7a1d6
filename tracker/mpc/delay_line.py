"""What a tracker knows of its own commands on their way to the car.

The runner holds each command in a delay line for ``plant.actuator_delay_s`` before the car
receives it. A tracker that knows the delay ``d`` also knows which of its commands the car
is executing at any time ``tau``: the newest one issued at or before ``tau - d`` (before
the first, the initial actuation). Latency compensation predicts the measured
state forward over the latency "with the previous inputs"; the exact previous inputs are
these, the commands already in the delay line, not the last one held.

:class:`IssuedInputs` records the commands a tracker issued and cuts any time interval into
pieces with one applied input each, so a model can be integrated across it piece by piece.
"""

from __future__ import annotations

import collections
import math

import numpy as np

from cosim.core.exceptions import ConfigError

_TIME_EPS_S = 1e-9
"""Slack when comparing simulated times, against float round-off of sums of periods."""


class IssuedInputs:
    """The commands one tracker issued, and what the car applies when.

    Args:
      delay_s: the transport delay the tracker believes in (0: applied when issued).
      initial: the input vector the car applies before the first issued command.
    """

    def __init__(self, delay_s: float, initial: np.ndarray) -> None:
        if not (math.isfinite(delay_s) and delay_s >= 0.0):
            raise ConfigError(f"delay_s = {delay_s!r}: expected a number >= 0")
        self.delay_s = float(delay_s)
        self.reset(initial)

    def reset(self, initial: np.ndarray) -> None:
        """Forget every issued command; the car applies ``initial`` until told otherwise."""
        self._initial = np.array(initial, dtype=float)
        self._issued: collections.deque[tuple[float, np.ndarray]] = collections.deque()

    def record(self, t_s: float, inputs: np.ndarray) -> None:
        """The tracker issued ``inputs`` at ``t_s`` (times must not decrease)."""
        if self._issued and t_s < self._issued[-1][0] - _TIME_EPS_S:
            raise ValueError(f"t_s = {t_s}: expected at least {self._issued[-1][0]}")
        self._issued.append((float(t_s), np.array(inputs, dtype=float)))

    def last_issued(self) -> np.ndarray:
        """The newest issued input (the initial one before any)."""
        return (self._issued[-1][1] if self._issued else self._initial).copy()

    def applied_at(self, t_s: float) -> np.ndarray:
        """The input the car executes at ``t_s``: issued at or before ``t_s - delay_s``."""
        applied = self._initial
        for issued_t_s, inputs in self._issued:
            if issued_t_s + self.delay_s > t_s + _TIME_EPS_S:
                break
            applied = inputs
        return applied.copy()

    def segments(self, start_s: float, end_s: float) -> list[tuple[float, np.ndarray]]:
        """``[(duration_s, applied input), ...]`` covering ``[start_s, end_s]`` in order.

        Pieces change where an issued command reaches the car (its time plus the delay);
        pieces shorter than a nanosecond are dropped. Commands issued at ``end_s - delay_s``
        or later do not reach the car within the interval.
        """
        pieces: list[tuple[float, np.ndarray]] = []
        t, applied = start_s, self.applied_at(start_s)
        for issued_t_s, inputs in self._issued:
            arrival_s = issued_t_s + self.delay_s
            if arrival_s <= start_s + _TIME_EPS_S:
                continue
            if arrival_s >= end_s - _TIME_EPS_S:
                break
            if arrival_s - t > _TIME_EPS_S:
                pieces.append((arrival_s - t, applied))
            t, applied = arrival_s, inputs.copy()
        if end_s - t > _TIME_EPS_S:
            pieces.append((end_s - t, applied))
        return pieces

    def forget_before(self, t_s: float) -> None:
        """Drop the commands that no interval starting at ``t_s`` or later needs."""
        while len(self._issued) > 1 and self._issued[1][0] + self.delay_s <= t_s + _TIME_EPS_S:
            self._initial = self._issued.popleft()[1]
        if len(self._issued) == 1 and self._issued[0][0] + self.delay_s <= t_s + _TIME_EPS_S:
            self._initial = self._issued.popleft()[1]
