"""Monte Carlo ensembles of runs: run a scenario over seeds and judge the filter's consistency.

Each member is one run of the same configuration with another seed (so independent sensor
noise, disturbances and initial estimate); its NEES series is read back from its log
(:func:`cosim.plots.data.load_estimation`, over ``x, y, yaw, vx``) and its NIS sums come from
its metrics (``nis_<sensor>`` times ``nis_dof_<sensor>``, and the same after the settling
time from ``nis_settled_<sensor>``). :func:`judge` hands them to
:func:`estimation.consistency.ensemble_consistency` (ANEES per time step with its chi-square
band; NIS per degree of freedom per sensor). Used by ``bench/estimator_consistency.py`` and
by the slow consistency tests.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim.plots.data import load_estimation
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import ScenarioConfig
from cosim.simulation.workshop import Workshop
from estimation.consistency import (
    SETTLE_S,
    EnsembleConsistency,
    anees_standard_error,
    ensemble_consistency,
    window_means,
)

NIS_PREFIX = "nis_dof_"
SETTLED_NIS_PREFIX = "nis_settled_dof_"
GATED_PREFIX = "gated_first_s_"
TESTED_PREFIX = "tested_first_s_"
"""Metrics: a sensor's updates in the first second with a NIS (what its gate tested)."""


@dataclass(frozen=True)
class EnsembleMember:
    """What the consistency test needs of one run."""

    seed: int
    t_s: np.ndarray
    nees: np.ndarray
    nis_sum: Mapping[str, float]
    nis_dof: Mapping[str, int]
    metrics: Mapping[str, object]
    nis_settled_sum: Mapping[str, float] = dataclasses.field(default_factory=dict)
    """Per sensor, the summed NIS of the updates after the settling time."""
    nis_settled_dof: Mapping[str, int] = dataclasses.field(default_factory=dict)
    gated_first_s: Mapping[str, int] = dataclasses.field(default_factory=dict)
    """Per sensor, the updates the gate refused (in whole or in part) in the first second."""
    normalized_errors: Mapping[str, np.ndarray] = dataclasses.field(default_factory=dict)
    """Per state the truth logs, its error squared over the filter's variance of it at each
    of ``t_s`` (:func:`state_consistency`)."""


def _sums(metrics: Mapping[str, object], dof_prefix: str, nis_prefix: str
          ) -> tuple[dict[str, float], dict[str, int]]:
    """Per sensor, the summed NIS and summed channels from a run's metrics."""
    dofs = {key.removeprefix(dof_prefix): int(value)  # type: ignore[call-overload]
            for key, value in metrics.items() if key.startswith(dof_prefix)}
    sums = {sensor: float(metrics[f"{nis_prefix}{sensor}"]) * count  # type: ignore[arg-type]
            for sensor, count in dofs.items()}
    return sums, dofs


class IncompleteRun(RuntimeError):
    """An ensemble's run that ended before its end (the car spun, left the road ...): it
    has no NEES over the whole manoeuvre to judge."""

    def __init__(self, seed: int, reason: str) -> None:
        super().__init__(f"seed {seed}: the run did not complete ({reason})")
        self.seed = seed
        self.reason = reason


def run_member(config: ScenarioConfig, seed: int, out_dir: Path, keep_log: bool = False,
               workshop: Workshop | None = None) -> EnsembleMember:
    """Run ``config`` with ``seed`` into ``out_dir`` and read back its NEES and NIS;
    ``workshop`` lends the parts of the ensemble's earlier runs (the same numbers)."""
    path = Path(out_dir) / f"{config.name}-{config.estimator.name}-{seed}.mcap"
    result = run(dataclasses.replace(config, seed=seed), path, workshop=workshop)
    if not result.completed:
        raise IncompleteRun(seed, result.abort_reason)
    errors = load_estimation(path)
    if not keep_log:
        path.unlink()
    if errors is None or errors.nees is None:
        raise RuntimeError(f"seed {seed}: the log has no NEES (estimator without covariance)")
    sums, dofs = _sums(result.metrics, NIS_PREFIX, "nis_")
    settled_sums, settled_dofs = _sums(result.metrics, SETTLED_NIS_PREFIX, "nis_settled_")
    gated = {key.removeprefix(GATED_PREFIX): int(value)  # type: ignore[call-overload]
             for key, value in result.metrics.items() if key.startswith(GATED_PREFIX)}
    normalized = {name: (errors.error[name] / errors.sigma[name]) ** 2
                  for name in errors.error}
    return EnsembleMember(seed, errors.t_s, errors.nees, sums, dofs, result.metrics,
                          settled_sums, settled_dofs, gated, normalized)


@dataclass(frozen=True)
class StateConsistency:
    """One state's error squared over the filter's variance of it, averaged over the runs
    (:func:`state_consistency`): 1 where the filter's variance of the state is its error's,
    under 1 where the filter is under-confident in it, over 1 where over-confident. The
    NEES of several states can sit in its band while one of them is off and another off the
    other way; this says which."""

    state: str
    mean: float
    """Over every run and step after the settling time."""
    windows: tuple[tuple[float, float], ...]
    """``(start_s, mean)`` of consecutive 1 s windows from the settling time on."""


def state_consistency(members: Sequence[EnsembleMember], settle_s: float = SETTLE_S,
                      window_s: float = 1.0) -> list[StateConsistency]:
    """Per state every member logs, ``e^2 / P_ii`` averaged over the runs at each step after
    ``settle_s``, its mean and its ``window_s`` window means (members cut to the shortest
    run's samples, as :func:`judge` cuts them)."""
    if not members:
        raise ValueError("no runs to judge")
    steps = min(m.t_s.size for m in members)
    t_s = members[0].t_s[:steps]
    settled = t_s >= settle_s - 1e-9
    shared = [name for name in members[0].normalized_errors
              if all(name in m.normalized_errors for m in members)]
    figures = []
    for name in shared:
        per_step = np.mean([m.normalized_errors[name][:steps] for m in members], axis=0)
        windows = window_means(t_s, per_step, float(settle_s), window_s)
        figures.append(StateConsistency(name, float(np.mean(per_step[settled])),
                                        tuple(windows)))
    return figures


def judge(members: Sequence[EnsembleMember], probability: float = 0.95,
          settle_s: float = SETTLE_S, settled_nis: bool = False) -> EnsembleConsistency:
    """The consistency figures of the members (cut to the shortest run's samples); with
    ``settled_nis`` the NIS is that of the updates after the settling time only (the
    runs' ``nis_settled_<sensor>``, whose settling time is :data:`SETTLE_S`)."""
    t_s, nees = _nees_matrix(members)
    return ensemble_consistency(
        t_s,
        nees,
        [m.nis_settled_sum if settled_nis else m.nis_sum for m in members],
        [m.nis_settled_dof if settled_nis else m.nis_dof for m in members],
        probability=probability,
        settle_s=settle_s,
    )


def anees_error(members: Sequence[EnsembleMember],
                settle_s: float = SETTLE_S) -> tuple[float, float]:
    """The members' mean ANEES's standard error over the runs, and the one independent steps
    would give (:func:`estimation.consistency.anees_standard_error`)."""
    return anees_standard_error(*_nees_matrix(members), settle_s=settle_s)


def _nees_matrix(members: Sequence[EnsembleMember]) -> tuple[np.ndarray, np.ndarray]:
    """The members' times and NEES, one row per run, cut to the shortest run's samples."""
    if not members:
        raise ValueError("no runs to judge")
    steps = min(m.t_s.size for m in members)
    return members[0].t_s[:steps], np.vstack([m.nees[:steps] for m in members])
