"""What a Kalman update works with: the channels it fuses, an update computed but not yet
committed, and the innovation of a group of channels (Bar-Shalom, Li, Kirubarajan,
"Estimation with Applications to Tracking and Navigation", Wiley 2001, sec. 5.2: the
innovation ``y = z - h(x)`` and its covariance ``S``)."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
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

    @functools.cached_property
    def column_index(self) -> np.ndarray:
        """:attr:`measurement_columns` as an index array, made once (indexing with a list
        converts it at every measurement)."""
        return np.array(self.measurement_columns, dtype=np.intp)

    @classmethod
    def of(cls, model: MeasurementModel, names: tuple[str, ...],
           believed: Mapping[str, float]) -> Selection:
        """The channels of ``model`` a measurement named ``names`` gives, each with the
        variance the filter believes: the model's error ``model_sigma^2`` plus the
        sensor's noise as believed (``believed``: channel to variance)."""
        model_rows, columns = model.select(names)
        angle_rows = tuple(i for i, row in enumerate(model_rows)
                           if model.channels[row] in model.angle_channels)
        variance = np.array([model.model_sigma[row] ** 2 + believed.get(model.channels[row], 0.0)
                             for row in model_rows])
        return cls(model_rows, columns, angle_rows, variance)

    def gate_key(self, model: MeasurementModel,
                 group: tuple[int, ...]) -> tuple[str, tuple[str, ...]]:
        """Which channels (this selection's rows ``group`` of ``model``) a run of gate
        failures belongs to, for ``gate_release_s``."""
        return model.sensor, tuple(model.channels[self.model_rows[i]] for i in group)


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


def normalised_innovation_squared(trial: TrialUpdate) -> float:
    """The NIS ``y' S^-1 y`` of a trial update (``S`` symmetrised; one channel divided,
    several whitened by ``S``'s Cholesky factor); NaN when ``S`` is not positive definite."""
    s_matrix = 0.5 * (trial.innovation_covariance + trial.innovation_covariance.T)
    innovation = trial.innovation.reshape(-1)
    if innovation.size == 1:
        if not s_matrix[0, 0] > 0.0:
            return math.nan
        return float(innovation[0] ** 2 / s_matrix[0, 0])
    try:
        cholesky = np.linalg.cholesky(s_matrix)
    except np.linalg.LinAlgError:
        return math.nan
    whitened = np.linalg.solve(cholesky, innovation)
    return float(whitened @ whitened)


def block_nis(trial: TrialUpdate, sizes: list[int]) -> tuple[float, ...]:
    """Each measurement's NIS in a joint trial update of several (their channels stacked,
    ``sizes`` of them each, in order): ``y_j' S_jj^-1 y_j`` over its block ``j`` of the
    innovation and of ``S`` (symmetrised), as the measurement alone against the same prior
    would give it; NaN for a singular block."""
    s_matrix = 0.5 * (trial.innovation_covariance + trial.innovation_covariance.T)
    innovation = trial.innovation.reshape(-1)
    nis: list[float] = []
    start = 0
    for size in sizes:
        block = slice(start, start + size)
        start = block.stop
        try:
            value = float(innovation[block] @ np.linalg.solve(s_matrix[block, block],
                                                              innovation[block]))
        except np.linalg.LinAlgError:
            value = math.nan
        nis.append(value)
    return tuple(nis)
