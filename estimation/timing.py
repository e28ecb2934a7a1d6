"""Time bookkeeping shared by the estimators: they only ever move forward in time."""

from __future__ import annotations

import math

from estimation.errors import TimeOrderError

TIME_TOLERANCE_S = 1e-9
"""Two times closer than this are the same instant (float sums of physics steps)."""


def forward_interval_s(current_t_s: float, t_s: float, who: str) -> float:
    """Seconds from ``current_t_s`` to ``t_s``: 0 for the same instant; a non-finite or
    earlier ``t_s`` raises (an estimator cannot go back in time)."""
    if not math.isfinite(t_s):
        raise ValueError(f"predict to t_s = {t_s!r}: expected a finite time")
    if t_s < current_t_s - TIME_TOLERANCE_S:
        raise TimeOrderError(
            f"predict to t_s = {t_s!r} s: the {who} is at {current_t_s!r} s and cannot go "
            "back in time"
        )
    interval_s = t_s - current_t_s
    return interval_s if interval_s > TIME_TOLERANCE_S else 0.0


def is_stale(current_t_s: float, t_s: float) -> bool:
    """Whether a measurement at ``t_s`` comes from before the estimator's time."""
    return t_s < current_t_s - TIME_TOLERANCE_S
