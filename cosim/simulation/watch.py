"""The run's judge: metrics, outcome and course monitors, requirements' signals, one observer.

:class:`RunWatch` is fed at the points of a step (:mod:`cosim.simulation.observers`):
at each log instant the tracking and estimation errors (:class:`MetricsAccumulator`), the
signals of the run's STL requirements, the outcome events (:class:`OutcomeMonitor`: off
the road, spun, rolled, wheels lifted ...) and the course's laps and sectors; NIS at each
fused measurement; the plan and its time at each control instant; each command as it
reaches the actuators. It is the one observer whose findings steer the loop: the first
terminal event (:data:`cosim.simulation.outcome.TERMINAL`) ends the run unless
``outcome.keep_going`` is set (:attr:`RunWatch.stopped_by`). Events are passed on to
``emit`` (the run gives them to every observer: the log writes them on ``/events``).
"""

from __future__ import annotations

from collections.abc import Callable

from cosim.core.records import ActuatorCommand, Command, Measurement, Plan
from cosim.core.sensor_names import TRUTH
from cosim.simulation.course import Course
from cosim.simulation.course_metrics import CourseMonitor
from cosim.simulation.metrics import MetricsAccumulator
from cosim.simulation.observers import LogInstant, Observer
from cosim.simulation.outcome import TERMINAL, Event, OutcomeMonitor
from cosim.simulation.requirements import SignalTrace
from cosim.simulation.scenario_config import ScenarioConfig
from estimation.update_result import UpdateResult


class RunWatch(Observer):
    """Metrics, monitors and the stop decision of one run (module docstring)."""

    def __init__(self, config: ScenarioConfig, course: Course,
                 emit: Callable[[Event], None]) -> None:
        reference = course.reference
        open_loop = config.tracker.name == "open-loop"
        self.metrics = MetricsAccumulator(reference, config.manoeuvre if open_loop else None)
        self.signals: SignalTrace | None = SignalTrace() if config.requirements else None
        """The signals of the run's STL requirements (none without requirements)."""
        bounds = course.bounds
        period_m = reference.length_m if reference.closed else None
        self.monitor = OutcomeMonitor(
            config.outcome, None if reference.closed else reference.length_m,
            tracks_path=not open_loop,
            road_edges=None if bounds is None else lambda s_m: bounds.at(s_m, period_m))
        self.course_monitor = CourseMonitor(course, config.plant)
        self.stopped_by: Event | None = None
        """The terminal event the run stops at, once it has happened."""
        self._keep_going = config.outcome.keep_going
        self._emit = emit

    def logged(self, instant: LogInstant) -> None:
        truth, metrics = instant.truth, self.metrics
        metrics.add_truth(truth)
        metrics.add_estimate(instant.estimate, truth)
        if self.signals is not None:
            self.signals.add({
                "t": instant.t_s, "cte_m": metrics.last_cte_m,
                "heading_err_rad": metrics.last_heading_err_rad,
                "speed_err_mps": metrics.last_speed_err_mps, "speed_mps": truth.speed_mps,
                "ref_speed_mps": metrics.last_ref_speed_mps, "lat_accel_mps2": truth.ay_mps2,
                "yaw_rate_radps": truth.yaw_rate_radps, "steer_rad": truth.steer_rad})
        for event in self.monitor.observe(truth, metrics.last_cte_m,
                                          metrics.last_heading_err_rad,
                                          metrics.last_path_s_m, instant.tyre_loads_n):
            self._emit(event)
            if event.kind in TERMINAL and not self._keep_going and self.stopped_by is None:
                self.stopped_by = event
        self.course_monitor.add_truth(truth, metrics.last_cte_m, metrics.last_path_s_m)

    def fused(self, t_s: float, measurement: Measurement, update: UpdateResult) -> None:
        del t_s
        if measurement.sensor != TRUTH:  # noise-free: NIS is undefined
            self.metrics.add_update(measurement.sensor, update, measurement.t_s)

    def controlled(self, t_s: float, plan: Plan, command: Command, step_time_s: float) -> None:
        del t_s, command
        self.metrics.add_plan(plan, step_time_s)

    def actuated(self, t_s: float, command: Command, actuator: ActuatorCommand) -> None:
        del t_s, actuator
        self.metrics.add_command(command)

    def collision(self, t_s: float, car: str) -> None:
        """The ego hit traffic car ``car``: the ``collision`` event (the run ends with it)."""
        self._emit(self.monitor.collision(t_s, car))
