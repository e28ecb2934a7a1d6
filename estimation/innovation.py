"""What a Kalman update works with: the channels it fuses, an update computed but not yet
committed, and the innovation of a group of channels (Bar-Shalom, Li, Kirubarajan,
"Estimation with Applications to Tracking and Navigation", Wiley 2001, sec. 5.2: the
innovation ``y = z - h(x)`` and its covariance ``S``)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from estimation.measurement_models import MeasurementModel
from estimation.state import wrap_angle


@dataclass(frozen=True)
class Selection:
    """Which channels of a measurement (by its names) the filter fuses, and how."""

    model_rows: tuple[int, ...]
    measurement_columns: tuple[int, ...]
    angle_rows: tuple[int, ...]
    model_variance: np.ndarray

    @functools.cached_property
    def every_column(self) -> bool:
        """Whether the measurement's every channel is fused, in its order (no selection)."""
        return self.measurement_columns == tuple(range(len(self.measurement_columns)))


@dataclass(frozen=True)
class TrialUpdate:
    """A filter's update of some channels, computed but not committed.

    ``innovation`` and ``innovation_covariance`` are the prior's ``y`` and ``S`` (with the
    measurement noise); ``mean``/``covariance`` the posterior the update would give.
    """

    innovation: np.ndarray
    innovation_covariance: np.ndarray
    mean: np.ndarray
    covariance: np.ndarray


@dataclass(frozen=True)
class Innovation:
    """One (group of) channel(s) of a measurement against the current belief."""

    rows: tuple[int, ...]
    """Rows of the measurement model."""
    nis: float
    trial: TrialUpdate


def residual_function(
    angle_rows: tuple[int, ...],
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``z - h`` with the angle channels (rows ``angle_rows``) wrapped to (-pi, pi]."""

    def residual(z: np.ndarray, h: np.ndarray) -> np.ndarray:
        difference = np.asarray(z, dtype=float) - np.asarray(h, dtype=float)
        for row in angle_rows:
            difference[row] = wrap_angle(difference[row])
        return difference

    return residual


@dataclass(frozen=True)
class CheckedMeasurement:
    """A measurement :meth:`estimation.fusion.KalmanFusion.update` can fuse: its model, the
    channels, their values and the time stamp."""

    model: MeasurementModel
    selection: Selection
    z: np.ndarray
    t_s: float
