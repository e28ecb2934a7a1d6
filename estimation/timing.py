"""Time bookkeeping shared by the estimators: they only ever move forward in time."""

from __future__ import annotations

import math

from estimation.errors import TimeOrderError

TIME_TOLERANCE_S = 1e-9
"""Two times closer than this, relative to their size (at least 1 s), are the same instant:
MuJoCo's clock is a float sum of physics steps, the runner's a product ``k dt``; after six
simulated minutes they differ by about 1e-9 s, after an hour by about 1e-8 s."""


def instant_tolerance_s(t_s: float) -> float:
    """How far from ``t_s`` another time is still the same instant (:data:`TIME_TOLERANCE_S`
    relative to ``t_s``, at least 1 s)."""
    return TIME_TOLERANCE_S * max(1.0, abs(t_s))


def forward_interval_s(current_t_s: float, t_s: float, who: str) -> float:
    """Seconds from ``current_t_s`` to ``t_s``: 0 for the same instant; a non-finite or
    earlier ``t_s`` raises (an estimator cannot go back in time)."""
    if not math.isfinite(t_s):
        raise ValueError(f"predict to t_s = {t_s!r}: expected a finite time")
    tolerance_s = instant_tolerance_s(current_t_s)
    if t_s < current_t_s - tolerance_s:
        raise TimeOrderError(
            f"predict to t_s = {t_s!r} s: the {who} is at {current_t_s!r} s and cannot go "
            "back in time"
        )
    interval_s = t_s - current_t_s
    return interval_s if interval_s > tolerance_s else 0.0


def is_stale(current_t_s: float, t_s: float) -> bool:
    """Whether a measurement at ``t_s`` comes from before the estimator's time."""
    return t_s < current_t_s - instant_tolerance_s(current_t_s)
