"""Errors raised by the estimators."""

from __future__ import annotations

from cosim.core.exceptions import CosimError


class EstimatorError(CosimError):
    """An estimator cannot continue (e.g. its state became non-finite)."""


class TimeOrderError(EstimatorError, ValueError):
    """An estimator was asked to go back in time."""
