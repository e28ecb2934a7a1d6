"""The log's topics: every MCAP topic a run writes, its schema, what it carries and when.

One table (after mcap's ``well_known`` module) for the names that the runner writes and the
reader, ``cosim inspect``, the plots, the video and the benches read back: a module names a
topic by its constant here, never by a string of its own. The topics are a contract (tools
outside cosim read them); ``docs/topics.md`` is generated from :data:`TOPICS` by
``python tools/metrics_doc.py``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from cosim.core.sensor_names import RADAR
from cosim.log import schemas

VEHICLE_TRUTH = "/vehicle/truth"
VEHICLE_ESTIMATE = "/vehicle/estimate"
CONTROL_COMMAND = "/control/command"
CONTROL_PLAN = "/control/plan"
CONTROL_ERRORS = "/control/errors"
REFERENCE_PATH = "/reference/path"
METRICS = "/metrics"
METRICS_LIVE = "/metrics/live"
ESTIMATOR_UPDATES = "/estimator/updates"
EVENTS = "/events"
PLANT_DISTURBANCE = "/plant/disturbance"
TF = "/tf"
SCENE = "/scene"
SCENE_CAR = "/scene/car"
SCENE_ESTIMATE = "/scene/estimate"
SCENE_PLAN = "/scene/plan"
SCENE_TRAFFIC = "/scene/traffic"
GNSS_FIX = "/gnss/fix"
TRAFFIC_CARS = "/traffic/cars"
TRAFFIC_GAP = "/traffic/gap"
ACC_GAINS = "/acc/gains"
ACC_OBJECTIVE = "/acc/objective"
ACC_MODE = "/acc/mode"
SENSORS_PREFIX = "/sensors/"


def sensor_topic(sensor: str) -> str:
    """``/sensors/<name>``: the measurements of the sensor ``sensor``
    (:mod:`cosim.core.sensor_names`)."""
    return f"{SENSORS_PREFIX}{sensor}"


@dataclass(frozen=True)
class Topic:
    """One topic of the log."""

    name: str
    schema: Mapping[str, Any]
    meaning: str
    when: str = "every run"


TOPICS: tuple[Topic, ...] = (
    Topic(VEHICLE_TRUTH, schemas.VEHICLE_STATE, "the true `VehicleState` at the log rate"),
    Topic(VEHICLE_ESTIMATE, schemas.ESTIMATE,
          "the filter's estimate at the log rate: the same field names for what it "
          "estimates, plus the covariance over `state_names`"),
    Topic(CONTROL_COMMAND, schemas.COMMAND,
          "the command as applied to the plant, with the wheel torques it became"),
    Topic(CONTROL_PLAN, schemas.PLAN,
          "the tracker's plan every control period: predicted states and inputs, cost, "
          "solve time, iterations, status, fallback"),
    Topic(CONTROL_ERRORS, schemas.TRACKING_ERRORS,
          "cross-track, heading and speed errors of the truth at each log step, as the "
          "metrics compute them"),
    Topic(REFERENCE_PATH, schemas.REFERENCE_PATH, "the reference path, once"),
    Topic(sensor_topic("<name>"), schemas.MEASUREMENT,
          "each sensor's measurements as the estimator receives them (faults applied)"),
    Topic(ESTIMATOR_UPDATES, schemas.ESTIMATOR_UPDATE,
          "each measurement the filter tested: sensor, accepted, NIS and its degrees of "
          "freedom"),
    Topic(METRICS, schemas.METRICS, "the run's metrics, once at the end (docs/metrics.md)"),
    Topic(METRICS_LIVE, schemas.LIVE_METRICS,
          "the running metrics over the run so far, once per second of sim time"),
    Topic(EVENTS, schemas.EVENT, "outcome events (spun, off_road, collision ...) when they "
          "happen", "runs with an event"),
    Topic(PLANT_DISTURBANCE, schemas.DISTURBANCE, "unmeasured disturbances applied to the "
          "plant", "runs with `disturbances:`"),
    Topic(TF, schemas.FRAME_TRANSFORM, "Foxglove: world -> base_link at the log rate"),
    Topic(SCENE, schemas.SCENE_UPDATE, "Foxglove: the reference path, cones and track "
          "edges, once"),
    Topic(SCENE_CAR, schemas.SCENE_UPDATE, "Foxglove: the car's body and wheels"),
    Topic(SCENE_ESTIMATE, schemas.SCENE_UPDATE,
          "Foxglove: the estimated pose and its 3-sigma ellipse"),
    Topic(SCENE_PLAN, schemas.SCENE_UPDATE, "Foxglove: the predicted path of each plan",
          "trackers whose plans have world positions"),
    Topic(GNSS_FIX, schemas.LOCATION_FIX, "Foxglove: each GNSS fix on the map (`geo:`)"),
    Topic(TRAFFIC_CARS, schemas.TRAFFIC_CARS, "the traffic cars' true poses",
          "runs with traffic"),
    Topic(TRAFFIC_GAP, schemas.TRAFFIC_GAP, "the true gap to the car ahead, its time gap "
          "and time to collision", "runs with traffic"),
    Topic(SCENE_TRAFFIC, schemas.SCENE_UPDATE, "Foxglove: the traffic cars",
          "runs with traffic"),
    Topic(sensor_topic(RADAR), schemas.RANGE_READING, "the forward range sensor's "
          "readings", "runs with traffic and `sensors.radar.enabled`"),
    Topic(ACC_GAINS, schemas.ACC_GAINS, "the ACC's gains and their estimates",
          "runs with the ACC"),
    Topic(ACC_OBJECTIVE, schemas.ACC_OBJECTIVE, "the objective extremum seeking minimises",
          "runs with the ACC"),
    Topic(ACC_MODE, schemas.ACC_MODE, "the ACC's mode (speed or gap), target and gap",
          "runs with the ACC"),
)
"""Every topic, in the order ``docs/topics.md`` lists them."""

_SCHEMAS: Mapping[str, Mapping[str, Any]] = MappingProxyType(
    {topic.name: topic.schema for topic in TOPICS})


def schema_of(topic: str) -> Mapping[str, Any]:
    """The JSON schema of the topic ``topic`` (a sensor's from its ``/sensors/`` prefix)."""
    if topic in _SCHEMAS:
        return _SCHEMAS[topic]
    if topic.startswith(SENSORS_PREFIX):
        return _SCHEMAS[sensor_topic("<name>")]
    raise KeyError(f"{topic}: not a topic of cosim's logs")


def markdown() -> str:
    """``docs/topics.md``: every topic, its schema's title, what it carries and when."""
    lines = [
        "# Log topics",
        "",
        "Generated from `cosim/log/topics.py` by `python tools/metrics_doc.py`: edit the",
        "table there, not this file. Every channel is JSON with a JSON schema (its title",
        "below); Foxglove's well-known schemas where one fits.",
        "",
        "| topic | schema | content | present in |",
        "|---|---|---|---|",
    ]
    for topic in TOPICS:
        lines.append(f"| `{topic.name}` | `{topic.schema['title']}` | {topic.meaning} | "
                     f"{topic.when} |")
    return "\n".join(lines) + "\n"
