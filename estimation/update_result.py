"""What an estimator returns for every measurement, and what it counts per sensor."""

from __future__ import annotations

import math
from dataclasses import dataclass

ACCEPTED = "accepted"
"""Fused."""
PARTIAL = "partial"
"""Fused, but some of its channels were gated out (e.g. one spinning wheel)."""
GATE_RELEASED = "gate-released"
"""Fused although a channel's NIS was above the gate, after ``gate_release_s`` of
consecutive rejections of that channel."""
GATE = "gate"
"""Rejected: every channel's NIS above the chi-square gate."""
NON_FINITE = "non-finite"
"""Rejected: NaN or infinite value, covariance or time stamp."""
STALE = "stale"
"""Rejected: time stamp before the estimator's time."""
INVALID = "invalid"
"""Rejected: innovation covariance not positive definite, or the update went non-finite."""
IGNORED = "ignored"
"""Not used: the estimator has no model of this sensor. Not a rejection."""

REASONS: tuple[str, ...] = (
    ACCEPTED,
    PARTIAL,
    GATE_RELEASED,
    GATE,
    NON_FINITE,
    STALE,
    INVALID,
    IGNORED,
)
"""Every value :attr:`UpdateResult.reason` takes."""


@dataclass(frozen=True)
class UpdateResult:
    """Outcome of fusing one measurement.

    ``nis`` is the normalised innovation squared ``y' S^-1 y`` against the prior (NaN when
    it could not be computed: ignored sensor, non-finite or stale measurement); ``dim`` is
    the number of channels fused or tested (0 for an ignored sensor); ``reason`` is one of
    :data:`REASONS` (exact strings, so callers can compare: ``reason == "ignored"``).

    ``joint_nis`` and ``joint_dim`` are the NIS and dimension of *all* the measurement's
    channels against the prior, whatever the gate then did: the figure consistency
    statistics need (a gated update is evidence of over-confidence, so dropping it would
    flatter the filter). NaN and 0 where no innovation was computed.
    """

    accepted: bool
    nis: float
    dim: int
    reason: str
    joint_nis: float = math.nan
    joint_dim: int = 0


@dataclass
class SensorCounts:
    """What happened to one sensor's measurements."""

    accepted: int = 0
    """Fused, at least in part (including after a gate release)."""
    rejected_gate: int = 0
    """Every channel's NIS above the chi-square gate."""
    rejected_nonfinite: int = 0
    """NaN or infinite value, covariance or time stamp."""
    rejected_stale: int = 0
    """Time stamp older than the filter's time."""
    rejected_invalid: int = 0
    """Innovation covariance not positive definite, or the update went non-finite."""
    ignored: int = 0
    """The filter has no model of this sensor (not a rejection)."""
    gate_released: int = 0
    """Channels fused although above the gate, after ``gate_release_s`` of rejections."""
    channels_gated: int = 0
    """Channels gated out, in rejected and in partly accepted measurements."""
    surprises: int = 0
    """Ungated measurements above the gate, fused after room was made in the directions of
    the process noise (a manoeuvre the model did not predict)."""

    def count_refusal(self, reason: str) -> None:
        """Count a measurement fused not at all before any gate: ignored (the filter has
        no model of its sensor), non-finite or stale."""
        if reason == IGNORED:
            self.ignored += 1
        elif reason == NON_FINITE:
            self.rejected_nonfinite += 1
        elif reason == STALE:
            self.rejected_stale += 1
        else:
            raise ValueError(f"reason {reason!r}: not a refusal before the gate")
