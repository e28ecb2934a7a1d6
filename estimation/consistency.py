"""Monte Carlo consistency of a filter: the chi-square band of the average NEES.

For a consistent filter the normalised estimation error squared (NEES) of an ``n``-state
error is chi-square distributed with ``n`` degrees of freedom. Averaged over ``N``
independent runs, ``N`` times the average is chi-square with ``N n`` degrees of freedom, so
the average lies, with probability ``p``, in ``[chi2_(1-p)/2 (N n), chi2_(1+p)/2 (N n)] / N``
(Bar-Shalom, Li, Kirubarajan, "Estimation with Applications to Tracking and Navigation",
2001, section 5.4.2, eq. 5.4.2-5). The runs' ``nees_mean`` metric (the time average over a
run, :mod:`cosim.simulation.metrics`) is what is averaged here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

NEES_DOF = 4
"""Degrees of freedom of the runs' NEES: x, y, yaw, vx
(:data:`cosim.simulation.metrics.NEES_STATES`)."""


def nees_band(dof: int, runs: int, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided ``probability`` band of the average NEES over ``runs`` independent runs of
    a consistent filter with a ``dof``-dimensional error."""
    if dof < 1 or runs < 1:
        raise ValueError(f"dof = {dof}, runs = {runs}: expected both >= 1")
    if not 0.0 < probability < 1.0:
        raise ValueError(f"probability = {probability!r}: expected a number in (0, 1)")
    tail = 0.5 * (1.0 - probability)
    return (
        float(chi2.ppf(tail, dof * runs)) / runs,
        float(chi2.ppf(1.0 - tail, dof * runs)) / runs,
    )


@dataclass(frozen=True)
class MonteCarloSummary:
    """The figures of a Monte Carlo of runs that differ only in their seed.

    RMSEs are root-mean-squares over the runs of each run's RMSE (so over every logged
    sample of every run, runs being of equal length).
    """

    estimator: str
    runs: int
    nees_mean: float
    nees_band: tuple[float, float]
    nees_min: float
    nees_max: float
    pos_rmse_m: float
    yaw_rmse_rad: float
    speed_rmse_mps: float
    nis_mean: float

    @property
    def consistent(self) -> bool:
        """Whether the average NEES lies inside the band."""
        return self.nees_band[0] <= self.nees_mean <= self.nees_band[1]

    def lines(self) -> list[str]:
        """A human-readable report."""
        low, high = self.nees_band
        verdict = "inside" if self.consistent else "OUTSIDE"
        return [
            f"{self.estimator}: {self.runs} runs",
            f"  mean NEES ({NEES_DOF} DoF)   {self.nees_mean:8.3f}   95 % band "
            f"[{low:.3f}, {high:.3f}]: {verdict}   (runs {self.nees_min:.2f} .. "
            f"{self.nees_max:.2f})",
            f"  est_pos_rmse_m      {self.pos_rmse_m:8.4f}",
            f"  est_yaw_rmse_rad    {self.yaw_rmse_rad:8.5f}",
            f"  est_speed_rmse_mps  {self.speed_rmse_mps:8.4f}",
            f"  nis_mean            {self.nis_mean:8.3f}",
        ]


def summarise(
    estimator: str,
    metrics: Sequence[Mapping[str, object]],
    probability: float = 0.95,
) -> MonteCarloSummary:
    """Summary of the runs' metrics (each a run's ``metrics`` mapping)."""
    if not metrics:
        raise ValueError("no runs to summarise")

    def column(key: str) -> np.ndarray:
        values = np.array([float(m[key]) for m in metrics])  # type: ignore[arg-type]
        if not np.isfinite(values).all():
            raise ValueError(f"{key}: a run has no finite value")
        return values

    nees = column("nees_mean")

    def rms(key: str) -> float:
        return math.sqrt(float(np.mean(column(key) ** 2)))

    return MonteCarloSummary(
        estimator=estimator,
        runs=len(metrics),
        nees_mean=float(nees.mean()),
        nees_band=nees_band(NEES_DOF, len(metrics), probability),
        nees_min=float(nees.min()),
        nees_max=float(nees.max()),
        pos_rmse_m=rms("est_pos_rmse_m"),
        yaw_rmse_rad=rms("est_yaw_rmse_rad"),
        speed_rmse_mps=rms("est_speed_rmse_mps"),
        nis_mean=float(column("nis_mean").mean()),
    )
