"""The messages a run logs most often, built from its records in one place: in the run's
own process, or in the process that writes ``cosim run``'s log.

At every log instant (100 a second by default) a run logs the truth, the estimate with its
covariance, the transform tree, the tracking errors and, 25 times a second, the car's and
the estimate's scenes; with every sample a sensor's measurement and the filter's update
with it; with every plan the plan and its scene. Building those dictionaries is most of
what logging costs a run's loop. So the run hands the *records* (the truth, the estimate,
each measurement, each update, each plan; :mod:`cosim.core.records`) to a
:class:`RunMessageSink`:

- :class:`RunMessages` builds the messages and writes them to a recorder at once (a run
  that writes its own log: ``cosim.run``, ``--live``, the tests);
- :class:`cosim.log.packed_records.PackedMessages` packs the records' numbers as bytes
  (:mod:`struct`, ``ndarray.tobytes``: exact) and sends them down ``cosim run``'s pipe; the
  parent (:class:`cosim.log.piped_recorder.LogServer`) unpacks the same records
  (:class:`cosim.log.packed_records.PackedReader`) and hands them to a :class:`RunMessages`
  of its own, on the other core.

Either way the same code builds the same messages from the same numbers, in the order the
run produced them: the same file.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from cosim.core.records import Estimate, Measurement, Plan, VehicleState
from cosim.core.sensor_names import GNSS
from cosim.core.vehicle_params import CarParams
from cosim.log import foxglove, topics
from cosim.log.foxglove import GeoOrigin
from estimation.update_result import UpdateResult


@dataclass(frozen=True)
class MessageContext:
    """What the messages need beside the records: the same for the whole run."""

    car: CarParams
    """The simulated car's dimensions (the car scene's boxes)."""
    gnss_sigma_m: float
    """The GNSS receiver's position sigma (the ``LocationFix``'s covariance)."""
    geo: GeoOrigin
    """Where the world frame's origin is on the Earth (the ``LocationFix``'s latitude and
    longitude)."""


@dataclass(frozen=True)
class TrackingErrors:
    """The tracking errors the metrics computed at a log instant (``/control/errors``)."""

    cte_m: float
    heading_err_rad: float
    speed_err_mps: float
    ref_speed_mps: float


class MessageWriter(Protocol):
    """Where :class:`RunMessages` writes (a recorder)."""

    def register(self, topic: str, schema: Mapping[str, Any] | None = None) -> None: ...

    def write(self, topic: str, t_s: float, message: dict[str, Any]) -> None: ...

    def write_finite(self, topic: str, t_s: float, message: dict[str, Any]) -> None: ...


class RunMessageSink(Protocol):
    """Takes the records a run logs most often (module docstring)."""

    def instant(self, t_s: float, truth: VehicleState, biases: Mapping[str, float],
                estimate: Estimate, scene: bool, errors: TrackingErrors) -> None:
        """A log instant: the truth with the sensors' true ``biases``, the estimate at the
        truth's time, the tracking ``errors``; the scenes too where ``scene``."""

    def measurement(self, t_s: float, measurement: Measurement) -> None:
        """A measurement as a sensor delivered it at ``t_s``."""

    def update(self, t_s: float, sensor: str, update: UpdateResult) -> None:
        """The filter's update with a measurement of ``sensor`` delivered at ``t_s``."""

    def plan(self, t_s: float, plan: Plan) -> None:
        """A tracker's plan at ``t_s``."""


class RunMessages:
    """Builds the messages of the records and writes them to ``writer``."""

    def __init__(self, writer: MessageWriter, context: MessageContext) -> None:
        self._writer = writer
        self._context = context
        self._plan_scene_registered = False
        """``/scene/plan`` is registered with its first message (a tracker whose plans have
        no world positions never has one)."""

    def instant(self, t_s: float, truth: VehicleState, biases: Mapping[str, float],
                estimate: Estimate, scene: bool, errors: TrackingErrors) -> None:
        writer = self._writer
        truth_message = truth.to_message()
        truth_message.update(biases)
        writer.write_finite(topics.VEHICLE_TRUTH, t_s, truth_message)
        writer.write_finite(topics.VEHICLE_ESTIMATE, t_s, estimate.to_message())
        writer.write(topics.TF, t_s, foxglove.frame_transform(truth))
        if scene:
            writer.write(topics.SCENE_CAR, t_s, foxglove.car_scene(truth, self._context.car))
            writer.write(topics.SCENE_ESTIMATE, t_s, foxglove.estimate_scene(estimate))
        writer.write_finite(topics.CONTROL_ERRORS, t_s, {
            "t_s": t_s, "cte_m": errors.cte_m, "heading_err_rad": errors.heading_err_rad,
            "speed_err_mps": errors.speed_err_mps, "speed_mps": truth.speed_mps,
            "ref_speed_mps": errors.ref_speed_mps,
        })

    def measurement(self, t_s: float, measurement: Measurement) -> None:
        writer = self._writer
        writer.write_finite(topics.sensor_topic(measurement.sensor), t_s,
                            measurement.to_message())
        if measurement.sensor == GNSS and np.all(np.isfinite(measurement.values)):
            writer.write(topics.GNSS_FIX, t_s, foxglove.location_fix(
                measurement["x_m"], measurement["y_m"], t_s, self._context.gnss_sigma_m,
                self._context.geo))

    def update(self, t_s: float, sensor: str, update: UpdateResult) -> None:
        self._writer.write_finite(topics.ESTIMATOR_UPDATES, t_s, {
            "t_s": t_s, "sensor": sensor, "accepted": update.accepted, "nis": update.nis,
            "dof": update.dim, "reason": update.reason})

    def plan(self, t_s: float, plan: Plan) -> None:
        writer = self._writer
        writer.write_finite(topics.CONTROL_PLAN, t_s, plan.to_message())
        scene = foxglove.plan_scene(plan)
        if scene is None:  # no world positions in this tracker's plans
            return
        if not self._plan_scene_registered:
            writer.register(topics.SCENE_PLAN)
            self._plan_scene_registered = True
        writer.write(topics.SCENE_PLAN, t_s, scene)
