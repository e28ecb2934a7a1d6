"""A filter that is inconsistent over a run: said at the end of it, whatever caused it.

:mod:`cosim.simulation.belief_check` speaks when a sensor's figure and the filter's belief
about it differ. A filter can be inconsistent with every figure matched too: its process
model does not fit the manoeuvre (a circuit's long curves, a heavier car than its model, a
generated circuit's tight turns), and then the controller acts on an estimate whose error
is several times what the filter believes. Two signs, from the run's own metrics:

- ``nees_mean``, the normalised estimation error squared over (x, y, yaw, speed), 4
  degrees of freedom: about 4 for a consistent filter. One run's time average of a
  correlated sequence is a weak test (:mod:`estimation.consistency` judges ensembles), so
  the alarm is a factor of :data:`NEES_FACTOR` above it: an error covariance understated
  that much is no sampling accident;
- a sensor's NIS per degree of freedom outside :data:`cosim.simulation.belief_check`'s
  band while its figure and belief agree (where they differ, the belief check says it).

One line each, as a warning and on ``/events`` (kind ``filter_inconsistent``); the outcome
does not change. The metric ``filter_warnings`` counts them (0 for a consistent run).
"""

from __future__ import annotations

from typing import Any

from cosim.simulation.belief_check import MIN_DOF, NIS_HIGH, NIS_LOW, SIGMA_KEYS

NEES_DOF = 4
"""Degrees of freedom of ``nees_mean`` (:data:`cosim.simulation.metrics.NEES_STATES`)."""

NEES_FACTOR = 2.5
"""``nees_mean`` above this many times its degrees of freedom is an alarm."""

MIN_DURATION_S = 2.0
"""Runs shorter than this say too little about consistency to warn."""


class FilterInconsistentWarning(UserWarning):
    """The filter's estimate was worse (or better) than it believed, over the run."""


def filter_warnings(metrics: dict[str, Any], reported: set[str]
                    ) -> list[tuple[str, float, float, str]]:
    """``(what, value, threshold, line)`` for each sign of an inconsistent filter in
    ``metrics``; sensors in ``reported`` (already named by the belief check) are left out."""
    found: list[tuple[str, float, float, str]] = []
    if float(metrics.get("sim_duration_s") or 0.0) < MIN_DURATION_S:
        return found
    gated = metrics.get("channels_gated")
    gated_text = f"; {gated} measurement channels gated" if gated else ""
    nees = metrics.get("nees_mean")
    if isinstance(nees, float) and nees > NEES_FACTOR * NEES_DOF:
        found.append(("nees_mean", nees, NEES_FACTOR * NEES_DOF, (
            f"filter inconsistent: nees_mean {nees:.3g} over the run, about {NEES_DOF} when "
            f"consistent: the estimate's error is some {(nees / NEES_DOF) ** 0.5:.1f} times "
            f"what the filter believes{gated_text}; its process model or noise does not "
            "fit this run (estimator.*_psd_* keys; docs/metrics.md)")))
    for sensor in SIGMA_KEYS:
        nis, dof = metrics.get(f"nis_{sensor}"), metrics.get(f"nis_dof_{sensor}", 0)
        if sensor in reported or not isinstance(nis, float) or dof < MIN_DOF \
                or NIS_LOW <= nis <= NIS_HIGH:
            continue
        way = "larger" if nis > NIS_HIGH else "smaller"
        found.append((f"nis_{sensor}", nis, NIS_HIGH if nis > NIS_HIGH else NIS_LOW, (
            f"filter inconsistent: nis_{sensor} {nis:.3g} per degree of freedom over the run, "
            f"outside [{NIS_LOW:g}, {NIS_HIGH:g}] with the sensor's figure and the filter's "
            f"belief alike: its innovations are {way} than the filter predicts")))
    return found
