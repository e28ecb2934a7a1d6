"""Traffic in a run's log: the cars, the gap, the range sensor and the ACC's decisions.

:class:`cosim.simulation.traffic_loop.TrafficLoop` simulates the traffic's part of a run (the
range sensor, collisions) and measures it (the gap and ACC metrics); whatever looks at that is
a :class:`TrafficObserver`, called at the loop's points in the order it takes them. A logged
run has one, :class:`TrafficLog`, which writes the messages; a run without a log has none and
builds no message at all. An observer changes nothing that is simulated.

Topics (schemas in :mod:`cosim.log.topics`): ``/traffic/cars`` (every car's true pose) and
``/scene/traffic`` (the cars as boxes, the range sensor's target in orange, at
``sim.scene_period_s``) and ``/traffic/gap`` (the true gap to the car ahead in the ego's lane,
its time gap, time to collision and the minimum safe gap) at each log instant;
``/sensors/radar`` (a reading as the sensor delivered it); ``/acc/gains``, ``/acc/objective``
and ``/acc/mode`` (the ACC's decision of each control step).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Protocol

from cosim.core.sensor_names import RADAR
from cosim.log import foxglove, topics

if TYPE_CHECKING:
    from cosim.core.traffic_records import CarPose, RangeReading
    from cosim.log.recorder import Recorder
    from tracker.cruise.law import AccStatus


class TrafficObserver(Protocol):
    """The points of the traffic's part of a step an observer is called at."""

    def cars(self, t_s: float, poses: tuple[CarPose, ...], scene: bool, target: str) -> None:
        """A log instant: every car's true pose; ``scene`` at a scene instant too, with the
        range sensor's current ``target``."""

    def gap(self, t_s: float, car: CarPose | None, gap_m: float, range_rate_mps: float,
            time_gap_s: float, ttc_s: float, safe_gap_m: float) -> None:
        """The same log instant: the true gap to the car ahead in the ego's lane (``car``,
        None without one) and what follows from it."""

    def ranged(self, t_s: float, reading: RangeReading) -> None:
        """The range sensor delivered ``reading``."""

    def decided(self, t_s: float, status: AccStatus) -> None:
        """The ACC decided its command of this control step."""


class TrafficLog:
    """Writes the traffic's topics to a recorder (module docstring)."""

    def __init__(self, recorder: Recorder, radar: bool, acc: bool) -> None:
        self._recorder = recorder
        self._radar = radar
        self._acc = acc

    def register(self) -> None:
        """Declare the topics this run writes (with the header, after every run's)."""
        recorder = self._recorder
        recorder.register(topics.TRAFFIC_CARS)
        recorder.register(topics.TRAFFIC_GAP)
        recorder.register(topics.SCENE_TRAFFIC)
        if self._radar:
            recorder.register(topics.sensor_topic(RADAR))
        if self._acc:
            recorder.register(topics.ACC_GAINS)
            recorder.register(topics.ACC_OBJECTIVE)
            recorder.register(topics.ACC_MODE)

    def cars(self, t_s: float, poses: tuple[CarPose, ...], scene: bool, target: str) -> None:
        cars = [pose.to_message() for pose in poses]
        self._recorder.write(topics.TRAFFIC_CARS, t_s, {"t_s": t_s, "cars": cars})
        if scene:
            self._recorder.write(topics.SCENE_TRAFFIC, t_s,
                                 foxglove.traffic_scene(t_s, cars, target))

    def gap(self, t_s: float, car: CarPose | None, gap_m: float, range_rate_mps: float,
            time_gap_s: float, ttc_s: float, safe_gap_m: float) -> None:
        self._recorder.write_finite(topics.TRAFFIC_GAP, t_s, {
            "t_s": t_s, "target": car.name if car is not None else "", "gap_m": gap_m,
            "range_rate_mps": range_rate_mps, "time_gap_s": time_gap_s, "ttc_s": ttc_s,
            "safe_gap_m": safe_gap_m,
            "target_speed_mps": car.speed_mps if car is not None else math.nan})

    def ranged(self, t_s: float, reading: RangeReading) -> None:
        self._recorder.write_finite(topics.sensor_topic(RADAR), t_s, reading.to_message())

    def decided(self, t_s: float, status: AccStatus) -> None:
        recorder = self._recorder
        recorder.write(topics.ACC_GAINS, t_s, status.gains_message())
        recorder.write_finite(topics.ACC_OBJECTIVE, t_s,
                              {"t_s": t_s, "objective": status.objective})
        recorder.write_finite(topics.ACC_MODE, t_s, {
            "t_s": t_s, "mode": status.mode, "gap_mode": status.mode == "gap",
            "target": status.target, "gap_m": status.gap_m,
            "desired_gap_m": status.desired_gap_m, "range_rate_mps": status.range_rate_mps,
            "speed_mps": status.speed_mps, "accel_mps2": status.accel_mps2})
