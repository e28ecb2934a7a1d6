"""What one run builds that the next may reuse: the plant, the estimator and the tracker.

Building a run's components costs about a quarter of a second, as much as simulating
several seconds: the sedan's MuJoCo model is compiled from its XML and settled on its
suspension, the filter builds its process and measurement models as CasADi graphs and
finds their compiled library by a hash of them, the MPC builds its NLP. None of that
depends on the run's seed or initial state, so a :class:`Workshop` keeps the last one of
each and hands it to the next run that asks for the same kind with the same
configuration, reset to the new run's start:

- the plant (:class:`cosim.plant.car.MujocoPlant`) for the same car and physics step,
  without traffic (a traffic car's script belongs to one run):
  :meth:`~cosim.plant.car.MujocoPlant.restart` at the new initial state;
- the estimator for the same estimator configuration and belief, if it is
  :class:`estimation.protocol.Restartable` (the built-in filters):
  ``restart`` from the new initial belief, drawn with the new run's generator;
- the tracker for the same tracker configuration, manoeuvre and control period, if it is
  one of cosim's own (not a plug-in, nor an FMU, whose state cosim cannot vouch for) and
  :class:`tracker.protocol.Resettable`: ``reset``.

A reused part runs bit for bit as a newly built one (``tests/test_workshop.py`` runs
differing configurations through one workshop and compares every metric with fresh runs).
A workshop serves one run at a time: a sweep worker keeps one for the tasks it is handed
(:func:`cosim.sweeps.execute.execute_batch`), a run without one builds everything afresh.
Configurations are compared by equality (they hold dictionaries, so they are not hashed).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import numpy as np

from cosim.core.initial_state import InitialState
from cosim.core.vehicle_params import PlantConfig, VehicleParams
from cosim.plant.car import MujocoPlant
from cosim.plant.traffic import Traffic
from estimation.config import EstimatorConfig
from estimation.protocol import Estimator, Restartable
from estimation.registry import estimator_class, make_estimator
from tracker.config import TrackerConfig
from tracker.manoeuvre import ManoeuvreConfig
from tracker.protocol import Closable, Resettable, Tracker
from tracker.registry import TRACKER_NAMES, make_tracker

Part = TypeVar("Part")


@dataclass
class _Kept(Generic[Part]):
    """The last part of one kind and what it was built from."""

    key: tuple[Any, ...]
    part: Part


class Workshop:
    """Keeps the last plant, estimator and tracker built, for the next run (module docstring).

    Each method returns the part a run needs: the kept one, reset to the run's start, when
    it was built from an equal configuration, else a newly built one (kept in its place).
    ``builds`` and ``reuses`` count both, per kind (for tests and benchmarks).
    """

    def __init__(self) -> None:
        self._plant: _Kept[MujocoPlant] | None = None
        self._estimator: _Kept[Estimator] | None = None
        self._tracker: _Kept[Tracker] | None = None
        self.builds: dict[str, int] = {"plant": 0, "estimator": 0, "tracker": 0}
        self.reuses: dict[str, int] = {"plant": 0, "estimator": 0, "tracker": 0}

    def plant(self, config: PlantConfig, physics_dt_s: float, initial: InitialState,
              traffic: Traffic | None = None) -> MujocoPlant:
        """The sedan ``config`` stepped at ``physics_dt_s``, at ``initial``."""
        if traffic is not None:  # scripted cars belong to their run: never kept
            self.builds["plant"] += 1
            return MujocoPlant(config, physics_dt_s, initial, traffic=traffic)
        key = (config, float(physics_dt_s))
        kept = self._plant
        if kept is not None and kept.key == key:
            self.reuses["plant"] += 1
            kept.part.restart(initial)
            return kept.part
        plant = self._built("plant", lambda: MujocoPlant(config, physics_dt_s, initial))
        self._plant = _Kept(key, plant)
        return plant

    def estimator(self, config: EstimatorConfig, initial: InitialState,
                  belief: VehicleParams, rng: np.random.Generator | None) -> Estimator:
        """The estimator ``config`` with the model ``belief``, its initial belief drawn
        around ``initial`` with ``rng`` (:func:`estimation.registry.make_estimator`)."""
        key = (estimator_class(config.name), config, belief)
        kept = self._estimator
        if kept is not None and kept.key == key and isinstance(kept.part, Restartable):
            self.reuses["estimator"] += 1
            kept.part.restart(initial, rng=rng)
            return kept.part
        estimator = self._built(
            "estimator", lambda: make_estimator(config, initial, belief, rng=rng))
        self._estimator = _Kept(key, estimator) if isinstance(estimator, Restartable) \
            else None
        return estimator

    def tracker(self, config: TrackerConfig, manoeuvre: ManoeuvreConfig,
                control_period_s: float) -> Tracker:
        """The tracker ``config`` (:func:`tracker.registry.make_tracker`), as newly built."""
        key = (config, manoeuvre, float(control_period_s))
        kept = self._tracker
        if kept is not None and kept.key == key:
            self.reuses["tracker"] += 1
            kept.part.reset()  # type: ignore[attr-defined]  # kept only if Resettable
            return kept.part
        tracker = self._built(
            "tracker", lambda: make_tracker(config, manoeuvre, control_period_s))
        reusable = (config.name in TRACKER_NAMES and isinstance(tracker, Resettable)
                    and not isinstance(tracker, Closable))
        self._tracker = _Kept(key, tracker) if reusable else None
        return tracker

    def _built(self, kind: str, build: Callable[[], Part]) -> Part:
        """``build()``, counted; the kept part of ``kind`` is dropped first, so a build
        that fails leaves nothing half-kept behind."""
        setattr(self, f"_{kind}", None)
        part = build()
        self.builds[kind] += 1
        return part
