"""The run's log as an observer: every message of a run, written where the step shows it.

:class:`RunLog` writes the header when it is made (channels, the run's metadata and
configuration, the truth beside the controller's belief, the simulated MJCF, the path and
the static scene) and then, at the points of a step (:mod:`cosim.simulation.observers`):

- at each log instant the truth (with the sensors' true biases), the estimate, the
  transform tree, the car and estimate scenes (every ``sim.scene_period_s``), the tracking
  errors and, once a second of simulated time, the running metrics (``/metrics/live``);
- each measurement delivered (and the GNSS fix as a Foxglove ``LocationFix``), each update
  of the filter with its NIS, each plan (and its scene where it has world positions), each
  command as it reaches the actuators, each disturbance and each event;
- at the end, the metrics (``/metrics`` and the ``metrics`` metadata record).

The truth, the estimate, the errors, the scenes, the measurements and the plans (most of a
log) are handed to the recorder's :meth:`~cosim.log.recorder.Recorder.messages` as records,
and their messages are built there (:mod:`cosim.log.run_messages`): by the run itself, or
by the process that writes ``cosim run``'s log, on the other core. A channel that may carry
nothing (``/events``, ``/scene/plan``) is registered with its first message. The topics and
their schemas are :mod:`cosim.log.topics`.
"""

from __future__ import annotations

import functools
import json
from typing import Any

import numpy as np

from cosim import __version__
from cosim.core import yaml_io
from cosim.core.config_fields import to_dict
from cosim.core.records import ActuatorCommand, Command, Measurement, Plan
from cosim.core.sensor_names import TRUTH
from cosim.log import foxglove, topics
from cosim.log.recorder import Recorder
from cosim.log.run_messages import MessageContext, TrackingErrors
from cosim.plant.disturbances import YawRateChange
from cosim.simulation.beliefs import mismatch_table, told
from cosim.simulation.course import Course
from cosim.simulation.metrics import MetricsAccumulator
from cosim.simulation.observers import LogInstant, Observer
from cosim.simulation.outcome import Event
from cosim.simulation.scenario_config import ScenarioConfig
from cosim.simulation.sensor_suite import SensorSuite
from cosim.simulation.traffic_log import TrafficLog
from estimation.update_result import UpdateResult

LIVE_METRICS_PERIOD_S = 1.0
"""``/metrics/live`` carries the running metrics once per second of sim time, so that
Foxglove's metrics panel fills during playback (``/metrics`` comes only at the end)."""

EVERY_RUN_TOPICS = (
    topics.VEHICLE_TRUTH, topics.VEHICLE_ESTIMATE, topics.CONTROL_COMMAND, topics.CONTROL_PLAN,
    topics.REFERENCE_PATH, topics.METRICS, topics.METRICS_LIVE, topics.ESTIMATOR_UPDATES,
    topics.CONTROL_ERRORS, topics.TF, topics.SCENE, topics.SCENE_CAR, topics.SCENE_ESTIMATE,
    topics.GNSS_FIX,
)
"""Channels every run registers before its first step (in this order)."""


def versions() -> dict[str, str]:
    """The versions of cosim and the libraries a run's numbers depend on (a copy of
    :func:`_installed_versions`)."""
    return dict(_installed_versions())


@functools.cache
def _installed_versions() -> dict[str, str]:
    """The versions, read once per process (what is imported does not change while the
    process runs). :mod:`importlib.metadata` is imported here: a run without a log (a
    sweep's) does not need it, nor the e-mail parser and zip reader it imports."""
    import importlib.metadata

    found = {"cosim": __version__}
    for package in ("mujoco", "dm-control", "casadi", "filterpy", "numpy", "scipy", "mcap"):
        try:
            found[package] = _version(package)
        except importlib.metadata.PackageNotFoundError:
            found[package] = "unknown"
    return found


def _version(package: str) -> str:
    """``importlib.metadata.version(package)``, read from the ``Version`` header of the
    package's metadata without the e-mail parser that function runs over the whole file
    (2.7 ms for the seven packages instead of 7.5 in a fresh process)."""
    import importlib.metadata

    distribution = importlib.metadata.distribution(package)
    for line in (distribution.read_text("METADATA") or "").splitlines():
        if not line:  # the headers end at the first empty line
            break
        if line.startswith("Version:"):
            return line[len("Version:"):].strip()
    return distribution.version


class RunLog(Observer):
    """Writes one run to ``recorder`` (module docstring)."""

    def __init__(self, recorder: Recorder, config: ScenarioConfig,
                 metrics: MetricsAccumulator, sensors: SensorSuite) -> None:
        self._recorder = recorder
        self._config = config
        self._metrics = metrics
        """The run's metrics, read for the tracking errors and the live metrics."""
        self._sensors = sensors
        self._messages = recorder.messages(MessageContext(
            config.plant, config.sensors.gnss.sigma_m, config.geo))
        """The truth, estimate, measurements and plans, their messages built by the
        recorder's side (:mod:`cosim.log.run_messages`: in another process for
        ``cosim run``)."""
        self._next_live_metrics_s = LIVE_METRICS_PERIOD_S
        self._registered: set[str] = set()
        """Channels registered with their first message."""

    def header(self, course: Course, mjcf_xml: str, traffic: TrafficLog | None) -> None:
        """Channels (traffic's after every run's and the sensors'), the run's metadata, the
        simulated MJCF, the path and the static scene."""
        recorder, config = self._recorder, self._config
        for topic in EVERY_RUN_TOPICS:
            recorder.register(topic)
        if config.disturbances:  # a channel exists only when it will carry messages
            recorder.register(topics.PLANT_DISTURBANCE)
        for name in self._sensors.names:
            recorder.register(topics.sensor_topic(name))
        if traffic is not None:
            traffic.register()  # the traffic's log (cosim.simulation.traffic_log)
        config_dict = to_dict(config)
        found = versions()
        recorder.add_metadata("run", {
            "scenario": config.name,
            "seed": str(config.seed),
            "epoch": config.sim.epoch,
            "epoch_ns": str(config.sim.epoch_ns),
            "config_yaml": yaml_io.dumps(config_dict),
            "config_json": json.dumps(config_dict),
            "versions": json.dumps(found),
            **{f"version_{k}": v for k, v in found.items()},
        })
        # The truth beside the belief, resolved (cosim.simulation.beliefs), for any reader.
        recorder.add_metadata("mismatch", {
            "table_json": json.dumps([row.as_dict() for row in mismatch_table(config_dict)]),
            "beliefs_from_plant_json": json.dumps(told(config_dict)),
        })
        recorder.add_attachment("sedan.xml", "application/xml", mjcf_xml.encode())
        reference = course.reference
        samples = reference.sample(np.arange(0.0, reference.length_m, 1.0))
        recorder.write(topics.REFERENCE_PATH, 0.0, {
            **{k: [float(v) for v in samples[k]] for k in samples},
            "speed_mps": reference.speed_mps,
            "ref_speed_mps": [float(v) for v in reference.speed_ref(samples["s_m"], 0.0)],
            "closed": reference.closed,
        })
        edges = course.bounds.edges(reference) if course.bounds is not None else None
        recorder.write(topics.SCENE, 0.0, foxglove.static_scene(
            samples["x_m"], samples["y_m"], course.cones_xy_m, edges, closed=reference.closed))

    def logged(self, instant: LogInstant) -> None:
        t_s, metrics = instant.t_s, self._metrics
        self._messages.instant(t_s, instant.truth, self._sensors.true_biases(),
                               instant.estimate, instant.scene, TrackingErrors(
                                   metrics.last_cte_m, metrics.last_heading_err_rad,
                                   metrics.last_speed_err_mps, metrics.last_ref_speed_mps))
        if t_s >= self._next_live_metrics_s - 1e-9:
            self._recorder.write_finite(topics.METRICS_LIVE, t_s, metrics.live(t_s))
            self._next_live_metrics_s += LIVE_METRICS_PERIOD_S

    def sensed(self, t_s: float, measurement: Measurement) -> None:
        self._messages.measurement(t_s, measurement)

    def fused(self, t_s: float, measurement: Measurement, update: UpdateResult) -> None:
        if measurement.sensor == TRUTH:
            return
        self._messages.update(t_s, measurement.sensor, update)

    def controlled(self, t_s: float, plan: Plan, command: Command, step_time_s: float) -> None:
        del command, step_time_s
        self._messages.plan(t_s, plan)

    def actuated(self, t_s: float, command: Command, actuator: ActuatorCommand) -> None:
        self._recorder.write(topics.CONTROL_COMMAND, t_s, {
            "t_s": t_s, "accel_mps2": command.accel_mps2, "steer_rad": command.steer_rad,
            "drive_torque_nm": actuator.drive_torque_nm,
            "brake_torque_nm": actuator.brake_torque_nm,
        })

    def disturbed(self, t_s: float, change: YawRateChange) -> None:
        self._recorder.write(topics.PLANT_DISTURBANCE, t_s, {
            "t_s": t_s, "kind": "heading_step", "heading_step_rad": change.angle_rad,
            "yaw_rate_change_radps": change.delta_radps})

    def event(self, event: Event) -> None:
        self._write_new(topics.EVENTS, event.t_s, event.to_message(), finite=True)

    def finished(self, values: dict[str, float | int | bool | str]) -> None:
        recorder = self._recorder
        recorder.write_finite(topics.METRICS, self._metrics.last_t_s, values)
        recorder.add_metadata("metrics", {"json": json.dumps(
            {k: (v if not isinstance(v, float) or np.isfinite(v) else None)
             for k, v in values.items()})})

    def _write_new(self, topic: str, t_s: float, message: dict[str, Any],
                   finite: bool = False) -> None:
        """A message on a channel registered with its first message."""
        if topic not in self._registered:
            self._recorder.register(topic)
            self._registered.add(topic)
        (self._recorder.write_finite if finite else self._recorder.write)(topic, t_s, message)
