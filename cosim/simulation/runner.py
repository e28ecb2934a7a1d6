"""The fixed-step multi-rate loop that runs one scenario and logs it to MCAP.

Clock at the physics step (``sim.physics_dt_s``). At each step k, at time t = k dt:

1. log the truth, the estimate, the tracking errors and the Foxglove scene (every
   ``sim.log_period_s``);
2. each sensor whose period is due samples the truth; the estimator fuses it;
3. every ``sim.control_period_s``: the tracker plans from the estimate; its command enters
   the actuator delay line (``plant.actuator_delay_s``);
4. commands that come due leave the delay line, the low-level layer turns them into wheel
   torques (with the controller's belief about the car) and the plant applies them;
5. the plant advances one physics step.

Every period is a whole number of physics steps (checked when the config is loaded), so
most steps have nothing of 1-4 due: the loop jumps from one step where something is due
to the next (:meth:`_Run.steps_to_next_due`) and the plant advances the steps between in
one call (:meth:`cosim.plant.car.MujocoPlant.advance_steps`, compiled C for the default
plant): the same steps in the same order, so the same numbers as one step at a time
(``tests/plant/test_compiled_steps.py``). A run
that aborts (diverging physics, an interrupt, an exception) still finishes its MCAP file,
with ``completed: false`` in its metrics.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import importlib.metadata
import json
import time
import warnings
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from threadpoolctl import threadpool_limits

from cosim import __version__
from cosim.core.config_fields import to_dict
from cosim.core.exceptions import PhysicsDivergenceError, TrackerFault
from cosim.core.records import Command, Estimate, Measurement, Plan, VehicleState
from cosim.core.sensor_names import GNSS, RADAR, TRUTH
from cosim.log import foxglove, topics
from cosim.log.recorder import McapRecorder, MessageMirror, NoLog, Recorder
from cosim.plant import disturbances
from cosim.plant.low_level import AccelToTorque
from cosim.plant.protocol import Plant
from cosim.sensing.faults import FaultInjector
from cosim.sensing.protocol import BiasedSensor, Sensor
from cosim.sensing.sensors import TruthSensor, make_sensors
from cosim.simulation.belief_check import BeliefMismatchWarning, belief_mismatches
from cosim.simulation.beliefs import mismatch_table, told
from cosim.simulation.course import Course, build_course
from cosim.simulation.course_metrics import CourseMonitor
from cosim.simulation.filter_health import FilterInconsistentWarning, filter_warnings
from cosim.simulation.metrics import MetricsAccumulator
from cosim.simulation.outcome import TERMINAL, Event, OutcomeMonitor
from cosim.simulation.requirements import SignalTrace, requirement_metrics
from cosim.simulation.run_control import StopRequest, WallClock, stop_on_signals
from cosim.simulation.scenario_config import ScenarioConfig, steps_per_period
from cosim.simulation.traffic_loop import CollisionError, TrafficLoop, build_traffic
from cosim.simulation.workshop import Workshop
from estimation.protocol import CountsUpdates, Estimator, JointUpdater, ObservableEstimator
from estimation.update_result import UpdateResult
from tracker.paths.reference_path import ReferencePath
from tracker.protocol import Closable, Tracker


@dataclass(frozen=True)
class RunResult:
    """What a run produced: its log, its metrics (every key declared in
    :mod:`cosim.simulation.metric_keys`), whether it ran to the end, and why not."""

    log_path: Path | None
    """The MCAP log; None for a run without one (:func:`run_unlogged`)."""
    metrics: dict[str, float | int | bool | str]
    completed: bool
    abort_reason: str
    """Empty when the run completed; else why it stopped (``interrupted``, the error)."""

    @property
    def outcome(self) -> str:
        """How the run ended: ``ok``, an event (``off_road``, ``spun`` ...) or the abort
        (``interrupted``, ``diverged``, ``error``); see :mod:`cosim.simulation.outcome`."""
        return str(self.metrics.get("outcome", "ok"))

    @property
    def reason(self) -> str:
        """:attr:`abort_reason` (empty when the run completed)."""
        return self.abort_reason


def component_rng(seed: int, component: str) -> np.random.Generator:
    """The generator of one component, derived from the run's seed and the component's name.

    Keyed by name (CRC-32), not by position, so adding a sensor leaves every other
    component's random stream unchanged.
    """
    return np.random.default_rng([seed, zlib.crc32(component.encode())])


def scenario_course(config: ScenarioConfig) -> Course:
    """The course of the scenario: path, speed profile, gates, cones, track bounds."""
    return build_course(config.path, config.initial, config.plant, config.sim.duration_s,
                        config.tracker)


def start_speed_resolved(config: ScenarioConfig, reference: ReferencePath) -> ScenarioConfig:
    """With ``initial.speed_from_profile``, ``initial.speed_mps`` becomes the reference
    speed where the car starts (its projection on the path, at t = 0)."""
    initial = config.initial
    if not initial.speed_from_profile:
        return config
    s_m = reference.project(initial.x_m, initial.y_m).s_m
    speed_mps = float(reference.speed_ref(s_m, 0.0))
    return dataclasses.replace(config, initial=dataclasses.replace(initial, speed_mps=speed_mps))


def _versions() -> dict[str, str]:
    versions = {"cosim": __version__}
    for package in ("mujoco", "dm-control", "casadi", "filterpy", "numpy", "scipy", "mcap"):
        try:
            versions[package] = importlib.metadata.version(package)
        except importlib.metadata.PackageNotFoundError:
            versions[package] = "unknown"
    return versions


LIVE_METRICS_PERIOD_S = 1.0
"""``/metrics/live`` carries the running metrics once per second of sim time, so that
Foxglove's metrics panel fills during playback (``/metrics`` comes only at the end)."""


_EVERY_RUN_TOPICS = (
    topics.VEHICLE_TRUTH, topics.VEHICLE_ESTIMATE, topics.CONTROL_COMMAND, topics.CONTROL_PLAN,
    topics.REFERENCE_PATH, topics.METRICS, topics.METRICS_LIVE, topics.ESTIMATOR_UPDATES,
    topics.CONTROL_ERRORS, topics.TF, topics.SCENE, topics.SCENE_CAR, topics.SCENE_ESTIMATE,
    topics.GNSS_FIX,
)
"""Channels every run registers before its first step (in this order)."""


def _register_topics(recorder: Recorder, sensor_names: list[str],
                     disturbed: bool) -> None:
    for topic in _EVERY_RUN_TOPICS:
        recorder.register(topic)
    if disturbed:  # a channel exists only when it will carry messages
        recorder.register(topics.PLANT_DISTURBANCE)
    for name in sensor_names:
        recorder.register(topics.sensor_topic(name))


@dataclass
class _Clock:
    """The run's step counts: every period as a whole number of physics steps."""

    dt_s: float
    n_steps: int
    control_steps: int
    log_steps: int
    scene_steps: int
    delay_steps: int

    @classmethod
    def from_config(cls, config: ScenarioConfig) -> _Clock:
        sim, dt = config.sim, config.sim.physics_dt_s
        log_steps = steps_per_period(sim.log_period_s, dt, "sim.log_period_s")
        scene_steps = log_steps * steps_per_period(sim.scene_period_s, sim.log_period_s,
                                                   "sim.scene_period_s", "sim.log_period_s")
        return cls(
            dt_s=dt,
            n_steps=steps_per_period(sim.duration_s, dt, "sim.duration_s"),
            control_steps=steps_per_period(sim.control_period_s, dt, "sim.control_period_s"),
            log_steps=log_steps,
            scene_steps=scene_steps,
            delay_steps=steps_per_period(config.plant.actuator_delay_s, dt,
                                         "plant.actuator_delay_s"),
        )


class _Run:
    """The components of one run and the phases of one physics step."""

    def __init__(self, config: ScenarioConfig, recorder: Recorder,
                 tracker: Tracker | None = None, workshop: Workshop | None = None) -> None:
        """``tracker``, if given, is the run's tracker; ``workshop`` keeps parts of earlier
        runs for this one (:mod:`cosim.simulation.workshop`; a new one: all built afresh)."""
        workshop = workshop if workshop is not None else Workshop()
        self.clock = _Clock.from_config(config)
        self.recorder = recorder
        self.course = scenario_course(config)
        self.reference = self.course.reference
        config = start_speed_resolved(config, self.reference)
        self.config = config
        """The run's configuration, the start speed resolved (what the log records)."""
        self.course_monitor = CourseMonitor(self.course, config.plant)
        traffic = build_traffic(config)
        self.plant: Plant = workshop.plant(config.plant, self.clock.dt_s, config.initial,
                                           traffic)
        self.estimator: Estimator = workshop.estimator(
            config.estimator, config.initial, config.tracker.model,
            component_rng(config.seed, "estimator.initial"))
        self.tracker: Tracker = tracker if tracker is not None else \
            workshop.tracker(config.tracker, config.manoeuvre, config.sim.control_period_s)
        """The run's tracker; the Gymnasium environment passes one that replays its actions."""
        self.fuse: Callable[[list[Measurement]], list[UpdateResult]] = (
            self.estimator.update_many if isinstance(self.estimator, JointUpdater)
            else self._fuse_one_by_one)
        """Fuses the measurements of one instant: together where the estimator can
        (:class:`estimation.protocol.JointUpdater`), else one by one."""
        self._observable = self.estimator if isinstance(self.estimator, ObservableEstimator) \
            else None
        """The estimator, if it can be looked at between its steps (checked once: a
        protocol's ``isinstance`` costs some 4 us, and the log looks at every instant)."""
        self.low_level = AccelToTorque(config.tracker.model)
        self.sensors: list[Sensor] = make_sensors(config.sensors)
        if TRUTH in self.estimator.required_sensors:
            period_s = min(config.sim.log_period_s, config.sim.control_period_s)
            self.sensors.append(TruthSensor(period_s))
        self.sensor_steps = [
            steps_per_period(s.period_s, self.clock.dt_s, f"sensors.{s.name}.period_s")
            for s in self.sensors
        ]
        self._periods = (self.clock.log_steps, self.clock.control_steps, *self.sensor_steps)
        """Every period at which the loop has work, in physics steps."""
        self.rngs = {s.name: component_rng(config.seed, f"sensors.{s.name}")
                     for s in self.sensors}
        self.biased_sensors = [s for s in self.sensors if isinstance(s, BiasedSensor)]
        """Sensors whose true biases the truth message carries (the log only reads them)."""
        self.faults = {s.name: FaultInjector(config.faults, s.name, s.names)
                       for s in self.sensors}
        open_loop = config.tracker.name == "open-loop"
        self.signals: SignalTrace | None = SignalTrace() if config.requirements else None
        """The signals of the run's STL requirements (none without requirements)."""
        self.metrics = MetricsAccumulator(self.reference,
                                          config.manoeuvre if open_loop else None)
        bounds = self.course.bounds
        period_m = self.reference.length_m if self.reference.closed else None
        self.monitor = OutcomeMonitor(
            config.outcome, None if self.reference.closed else self.reference.length_m,
            tracks_path=not open_loop,
            road_edges=None if bounds is None else lambda s_m: bounds.at(s_m, period_m))
        self.delay_line: collections.deque[tuple[int, Command]] = collections.deque()
        self.yaw_rate_changes = collections.deque(disturbances.schedule(
            config.disturbances, self.clock.dt_s, component_rng(config.seed, "disturbances")))
        self._truth: VehicleState | None = None
        self.plan_scene_registered = False
        """``/scene/plan`` is registered with the first plan that has world positions."""
        self.next_live_metrics_s = LIVE_METRICS_PERIOD_S
        """Sim time of the next ``/metrics/live`` message."""
        self.events_registered = False
        """``/events`` is registered with the first event."""
        self.stopped_by: Event | None = None
        """The terminal event the run stops at (:data:`cosim.simulation.outcome.TERMINAL`),
        once it has happened."""
        self.traffic = None if traffic is None else \
            TrafficLoop(config, self.plant, traffic, recorder, self.tracker,
                        component_rng(config.seed, f"sensors.{RADAR}"))
        """Traffic, range sensor and ACC topics (:mod:`cosim.simulation.traffic_loop`)."""

    @property
    def truth(self) -> VehicleState:
        """The plant's true state now, read when first needed after a step (sensors and
        logging run every few physics steps; reading it after every step cost a sixth of
        the plant's time)."""
        if self._truth is None:
            self._truth = self.plant.state()
        return self._truth

    def write_header(self) -> None:
        """Channels, the run's metadata, the simulated MJCF, the path and the static scene."""
        recorder, config = self.recorder, self.config
        if not recorder.keeps:
            return
        _register_topics(recorder, [s.name for s in self.sensors],
                         bool(config.disturbances))
        if self.traffic is not None:
            self.traffic.register()
        config_dict = to_dict(config)
        versions = _versions()
        recorder.add_metadata("run", {
            "scenario": config.name,
            "seed": str(config.seed),
            "epoch": config.sim.epoch,
            "epoch_ns": str(config.sim.epoch_ns),
            "config_yaml": yaml.safe_dump(config_dict, sort_keys=False),
            "config_json": json.dumps(config_dict),
            "versions": json.dumps(versions),
            **{f"version_{k}": v for k, v in versions.items()},
        })
        # The truth beside the belief, resolved (cosim.simulation.beliefs), for any reader.
        recorder.add_metadata("mismatch", {
            "table_json": json.dumps([row.as_dict() for row in mismatch_table(config_dict)]),
            "beliefs_from_plant_json": json.dumps(told(config_dict)),
        })
        recorder.add_attachment("sedan.xml", "application/xml", self.plant.mjcf_xml.encode())
        samples = self.reference.sample(np.arange(0.0, self.reference.length_m, 1.0))
        recorder.write(topics.REFERENCE_PATH, 0.0, {
            **{k: [float(v) for v in samples[k]] for k in samples},
            "speed_mps": self.reference.speed_mps,
            "ref_speed_mps": [float(v) for v in self.reference.speed_ref(samples["s_m"], 0.0)],
            "closed": self.reference.closed,
        })
        course = self.course
        edges = course.bounds.edges(self.reference) if course.bounds is not None else None
        recorder.write(topics.SCENE, 0.0, foxglove.static_scene(
            samples["x_m"], samples["y_m"], course.cones_xy_m, edges,
            closed=self.reference.closed))

    def current_estimate(self, t_s: float) -> Estimate:
        """The estimator predicted to ``t_s``, for the controller: part of the loop (the
        filter's predictions follow the control and sensor instants, never the log's)."""
        self.estimator.predict(t_s)
        return self.estimator.estimate()

    def observed_estimate(self, t_s: float) -> Estimate:
        """The estimate at ``t_s`` without changing the estimator (for the log and the
        low-level layer): an estimator that cannot be looked at between its steps gives its
        latest belief as it stands."""
        if self._observable is not None:
            return self._observable.estimate_at(t_s)
        return self.estimator.estimate()

    def log(self, k: int, t_s: float) -> None:
        """The log's and the metrics' look at step ``k``: the truth, the estimate (observed,
        not changed), events; the messages only when the recorder keeps them.

        The estimate is predicted to the truth's own time stamp (the plant's clock, which
        the sensors stamp their measurements with too: ``t_s`` to a few 1e-18 s), so it is
        compared with the truth at the same instant, and the filter, predicting to the
        sensors' instant next, takes that prediction as made."""
        estimate = self.observed_estimate(self.truth.t_s)
        keeps = self.recorder.keeps
        if keeps:
            truth_message = self.truth.to_message()
            for sensor in self.biased_sensors:
                truth_message.update(sensor.true_biases())
            self.recorder.write_finite(topics.VEHICLE_TRUTH, t_s, truth_message)
            self.recorder.write_finite(topics.VEHICLE_ESTIMATE, t_s, estimate.to_message())
            self.recorder.write(topics.TF, t_s, foxglove.frame_transform(self.truth))
            if k % self.clock.scene_steps == 0:
                self.recorder.write(topics.SCENE_CAR, t_s,
                                    foxglove.car_scene(self.truth, self.config.plant))
                self.recorder.write(topics.SCENE_ESTIMATE, t_s,
                                    foxglove.estimate_scene(estimate))
        metrics = self.metrics
        metrics.add_truth(self.truth)
        metrics.add_estimate(estimate, self.truth)
        if self.signals is not None:  # the STL requirements' signals, at the log instants
            truth = self.truth
            self.signals.add({
                "t": t_s, "cte_m": metrics.cte_m.last,
                "heading_err_rad": metrics.heading_err_rad.last,
                "speed_err_mps": metrics.speed_err_mps.last, "speed_mps": truth.speed_mps,
                "ref_speed_mps": metrics.last_ref_speed_mps, "lat_accel_mps2": truth.ay_mps2,
                "yaw_rate_radps": truth.yaw_rate_radps, "steer_rad": truth.steer_rad})
        forces = self.plant.tyre_forces()
        for event in self.monitor.observe(
                self.truth, metrics.cte_m.last, metrics.heading_err_rad.last, metrics.last_path_s_m,
                None if forces is None else tuple(f.load_n for f in forces)):
            self.write_event(event)
            if event.kind in TERMINAL and not self.config.outcome.keep_going \
                    and self.stopped_by is None:
                self.stopped_by = event
        self.course_monitor.add_truth(self.truth, metrics.cte_m.last, metrics.last_path_s_m)
        if keeps:
            self.recorder.write_finite(topics.CONTROL_ERRORS, t_s, {
                "t_s": t_s, "cte_m": metrics.cte_m.last,
                "heading_err_rad": metrics.heading_err_rad.last,
                "speed_err_mps": metrics.speed_err_mps.last, "speed_mps": self.truth.speed_mps,
                "ref_speed_mps": metrics.last_ref_speed_mps,
            })
        if keeps and t_s >= self.next_live_metrics_s - 1e-9:
            self.recorder.write_finite(topics.METRICS_LIVE, t_s, metrics.live(t_s))
            self.next_live_metrics_s += LIVE_METRICS_PERIOD_S
        if self.traffic is not None:
            self.traffic.log(t_s, self.truth, scene=k % self.clock.scene_steps == 0)

    def _fuse_one_by_one(self, measurements: list[Measurement]) -> list[UpdateResult]:
        return [self.estimator.update(measurement) for measurement in measurements]

    def sense(self, k: int, t_s: float) -> None:
        if self.traffic is not None and self.traffic.radar_due(k):
            self.traffic.sense(t_s, self.truth)
        delivered = []
        for sensor, steps in zip(self.sensors, self.sensor_steps, strict=True):
            if k % steps:
                continue
            measurement = self.faults[sensor.name].apply(
                sensor.sample(self.truth, self.rngs[sensor.name]))
            if measurement is None:  # a dropout: nothing is delivered
                continue
            delivered.append(measurement)
            if not self.recorder.keeps:
                continue
            self.recorder.write_finite(topics.sensor_topic(sensor.name), t_s,
                                       measurement.to_message())
            if sensor.name == GNSS and np.all(np.isfinite(measurement.values)):
                self.recorder.write(topics.GNSS_FIX, t_s, foxglove.location_fix(
                    measurement["x_m"], measurement["y_m"], t_s,
                    self.config.sensors.gnss.sigma_m, self.config.geo))
        if not delivered:
            return
        updates = self.fuse(delivered)
        for measurement, update in zip(delivered, updates, strict=True):
            if measurement.sensor != TRUTH:  # noise-free: NIS is undefined
                self.metrics.add_update(measurement.sensor, update, measurement.t_s)
                if not self.recorder.keeps:
                    continue
                self.recorder.write_finite(topics.ESTIMATOR_UPDATES, t_s, {
                    "t_s": t_s, "sensor": measurement.sensor, "accepted": update.accepted,
                    "nis": update.nis, "dof": update.dim, "reason": update.reason})

    def control(self, k: int, t_s: float) -> None:
        estimate = self.current_estimate(t_s)
        # One timing scope for every tracker: the whole step (step_ms_*), not only the
        # solver call each tracker reports itself (solve_ms_*).
        start_s = time.perf_counter()
        command, plan = self.tracker.step(t_s, estimate, self.reference)
        step_time_s = time.perf_counter() - start_s
        if self.recorder.keeps:
            self.recorder.write_finite(topics.CONTROL_PLAN, t_s, plan.to_message())
            self.write_plan_scene(t_s, plan)
        self.metrics.add_plan(plan, step_time_s)
        self.delay_line.append((k + self.clock.delay_steps, command))
        if self.traffic is not None:
            self.traffic.after_control(t_s)

    def record_fault(self, error: TrackerFault) -> None:
        """The tracker's failure on ``/events``: kind ``tracker_fault``, the one-line
        reason and the traceback of the user's code in ``detail``."""
        if not self.events_registered:
            self.recorder.register(topics.EVENTS)
            self.events_registered = True
        t_s = self.metrics.last_t_s
        self.recorder.write_finite(topics.EVENTS, t_s, {
            "t_s": t_s, "kind": "tracker_fault", "value": float("nan"),
            "threshold": float("nan"), "detail": f"{error}\n{error.detail}".strip()})

    def record_collision(self, error: CollisionError) -> None:
        """The ``collision`` event on ``/events`` (the run ends with it)."""
        self.write_event(self.monitor.collision(error.t_s, error.car))

    def write_event(self, event: Event) -> None:
        """One event on ``/events`` (the channel exists only when it carries messages)."""
        if not self.events_registered:
            self.recorder.register(topics.EVENTS)
            self.events_registered = True
        self.recorder.write_finite(topics.EVENTS, event.t_s, event.to_message())

    def write_plan_scene(self, t_s: float, plan: Plan) -> None:
        scene = foxglove.plan_scene(plan)
        if scene is None:  # no world positions in this tracker's plans
            return
        if not self.plan_scene_registered:
            self.recorder.register(topics.SCENE_PLAN)
            self.plan_scene_registered = True
        self.recorder.write(topics.SCENE_PLAN, t_s, scene)

    def actuate(self, k: int, t_s: float) -> None:
        """Apply the commands that leave the delay line at step ``k``."""
        while self.delay_line and self.delay_line[0][0] <= k:
            _, command = self.delay_line.popleft()
            speed_mps = self.observed_estimate(t_s)["vx_mps"]
            actuator = self.low_level.convert(command, speed_mps)
            self.plant.apply(actuator)
            self.metrics.add_command(command)
            if not self.recorder.keeps:
                continue
            self.recorder.write(topics.CONTROL_COMMAND, t_s, {
                "t_s": t_s, "accel_mps2": command.accel_mps2, "steer_rad": command.steer_rad,
                "drive_torque_nm": actuator.drive_torque_nm,
                "brake_torque_nm": actuator.brake_torque_nm,
            })

    def disturb(self, k: int, t_s: float) -> None:
        """Apply the unmeasured disturbances due at step ``k`` (:mod:`cosim.plant.disturbances`)."""
        while self.yaw_rate_changes and self.yaw_rate_changes[0].step <= k:
            change = self.yaw_rate_changes.popleft()
            self.plant.add_yaw_rate(change.delta_radps)
            self._truth = None
            self.recorder.write(topics.PLANT_DISTURBANCE, t_s, {
                "t_s": t_s, "kind": "heading_step", "heading_step_rad": change.angle_rad,
                "yaw_rate_change_radps": change.delta_radps})

    def observe(self, k: int) -> bool:
        """Phases 1-2 of step ``k`` (log, sense); False at the end of the run (its last
        step, or a terminal event: :attr:`stopped_by`)."""
        t_s = k * self.clock.dt_s
        if k % self.clock.log_steps == 0:
            self.log(k, t_s)
            if self.stopped_by is not None:
                return False
        self.sense(k, t_s)
        return k < self.clock.n_steps

    def act(self, k: int) -> None:
        """Phases 4-5 of step ``k``: actuate, disturb, advance the plant."""
        t_s = k * self.clock.dt_s
        self.actuate(k, t_s)
        self.disturb(k, t_s)
        self.plant.advance()
        self._truth = None

    def steps_to_next_due(self, k: int) -> int:
        """Physics steps from step ``k`` to the next step at which anything is due: a log
        entry, a sensor, the controller, a command leaving the delay line, a disturbance,
        the run's end (1 with traffic, whose cars and range sensor follow every step)."""
        if self.traffic is not None:
            return 1
        clock = self.clock
        due = clock.n_steps
        for period in self._periods:
            due = min(due, (k // period + 1) * period)
        if self.delay_line:
            due = min(due, self.delay_line[0][0])
        if self.yaw_rate_changes:
            due = min(due, self.yaw_rate_changes[0].step)
        return max(due - k, 1)

    def loop(self, stop: StopRequest, progress: Callable[[float], None] | None) -> None:
        """Step ``k`` is observed, controlled and acted on where something is due; between
        such steps the plant advances in one call (:meth:`MujocoPlant.advance_steps`: in
        compiled code), with nothing else to do there: the same steps, the same answers.
        ``progress(0.0)`` comes first: the run's signal handler is in place from then on."""
        clock = self.clock
        k = 0
        if progress is not None:
            progress(0.0)
        while True:
            if not self.observe(k):
                return
            t_s = k * clock.dt_s
            if k % clock.control_steps == 0:
                self.control(k, t_s)
            self.actuate(k, t_s)
            self.disturb(k, t_s)
            n = self.steps_to_next_due(k)
            self.plant.advance_steps(n)
            self._truth = None
            if stop.signal_name:
                raise KeyboardInterrupt
            if progress is not None and (k + n) // 500 != k // 500:
                progress((k + n) // 500 * 500 / clock.n_steps)
            k += n


def run(
    config: ScenarioConfig,
    out_path: Path,
    progress: Callable[[float], None] | None = None,
    mirror: MessageMirror | None = None,
    workshop: Workshop | None = None,
) -> RunResult:
    """Run one scenario to ``out_path``; ``progress`` is called with the fraction done;
    ``mirror`` sees every message as it is written (``cosim run --live``); ``workshop``
    holds parts earlier runs built, for this one to reuse (:mod:`cosim.simulation.workshop`).

    SIGINT and SIGTERM stop the run between two physics steps; the log is finished with
    ``completed: false`` and the result says ``interrupted``. A ``SystemExit`` (or another
    ``BaseException`` but ``KeyboardInterrupt``) raised by code inside the loop, a user's
    plug-in calling ``sys.exit``, ends the run the same way with outcome ``error`` and the
    reason; an ordinary exception is raised on once the log is finished.
    """
    wall_start = time.perf_counter()
    with McapRecorder(out_path, epoch_ns=config.sim.epoch_ns, mirror=mirror) as recorder:
        metrics, completed, abort_reason = _run_with(config, recorder, progress, wall_start,
                                                     workshop)
    return RunResult(Path(out_path), metrics, completed, abort_reason)


def run_unlogged(config: ScenarioConfig,
                 progress: Callable[[float], None] | None = None,
                 workshop: Workshop | None = None) -> RunResult:
    """:func:`run` without a log (``log_path`` None): the same simulation and metrics, bit
    for bit, with no messages built, encoded or written (a sweep that keeps no logs: they
    would be deleted unread)."""
    wall_start = time.perf_counter()
    metrics, completed, abort_reason = _run_with(config, NoLog(), progress, wall_start,
                                                 workshop)
    return RunResult(None, metrics, completed, abort_reason)


def _run_with(
    config: ScenarioConfig, recorder: Recorder, progress: Callable[[float], None] | None,
    wall_start: float, workshop: Workshop | None,
) -> tuple[dict[str, float | int | bool | str], bool, str]:
    """The run of :func:`run` through ``recorder``: its metrics, whether it completed and
    why not."""
    completed, abort_reason, abort = False, "", ""
    # One BLAS thread: the matrices here are small, and an idle BLAS thread spinning on
    # the other core makes MPC solve times jitter (docs/defaults.md).
    with threadpool_limits(limits=1, user_api="blas"), contextlib.ExitStack() as release:
        state = _Run(config, recorder, workshop=workshop)
        if isinstance(state.tracker, Closable):  # released however the run ends
            release.callback(state.tracker.close)
        state.write_header()
        recorder.publish()  # the run starts for real: the log takes its final name
        clock = WallClock(wall_start, time.perf_counter())  # set-up (and any build) ends
        try:
            with stop_on_signals() as stop:
                state.loop(stop, progress)
            completed = state.stopped_by is None
            if state.stopped_by is not None:
                event = state.stopped_by
                abort_reason = (f"stopped at {event.kind} (t = {event.t_s:.2f} s; "
                                "outcome.keep_going: true runs on)")
        except PhysicsDivergenceError as error:
            abort_reason, abort = str(error), "diverged"
        except TrackerFault as error:  # a plug-in tracker failed: a result, not a crash
            abort_reason, abort = str(error), "error"
            state.record_fault(error)
        except CollisionError as error:  # the ego hit a traffic car: a result
            abort_reason, abort = "collision", "collision"
            state.record_collision(error)
        except KeyboardInterrupt:
            abort_reason = abort = "interrupted"
        except Exception as error:  # the log is finished below, then the error goes on
            _finish(recorder, state, clock, False,
                    f"{type(error).__name__}: {error}", "error")
            raise
        except BaseException as error:  # noqa: BLE001 - SystemExit from a user's plug-in
            abort_reason, abort = f"{type(error).__name__} raised during the run: " \
                f"{error}", "error"
        if progress is not None:
            progress(1.0)
        metrics = _finish(recorder, state, clock, completed, abort_reason, abort)
    return metrics, completed, abort_reason


def _finish(recorder: Recorder, state: _Run, clock: WallClock, completed: bool,
            abort_reason: str, abort: str) -> dict[str, float | int | bool | str]:
    metrics = state.metrics
    estimator = state.estimator
    metrics.estimator_counts = estimator.counts() if isinstance(estimator, CountsUpdates) \
        else {}
    setup_time_s, wall_time_s = clock.times()
    values: dict[str, float | int | bool | str] = dict(metrics.result(wall_time_s, completed))
    values["setup_time_s"] = setup_time_s
    values.update(state.course_monitor.result())
    values["faults_injected"] = sum(f.injected for f in state.faults.values())
    values["outcome"] = state.monitor.outcome(abort)
    if state.traffic is not None:
        values.update(state.traffic.result())
    values.update(requirement_metrics(state.config.requirements, state.signals,
                                      state.config.sim.log_period_s))
    values["events"] = len(state.monitor.events)
    for event in state.monitor.events:
        values.setdefault(f"{event.kind}_t_s", event.t_s)
    if abort_reason:
        values["abort_reason"] = abort_reason
    mismatches = belief_mismatches(values, to_dict(state.config))
    values["belief_mismatches"] = len(mismatches)
    for mismatch in mismatches:
        state.write_event(Event("belief_mismatch", metrics.last_t_s, mismatch.nis,
                                mismatch.bound, mismatch.line))
        warnings.warn(mismatch.line, BeliefMismatchWarning, stacklevel=2)
    health = filter_warnings(values, {m.sensor for m in mismatches})
    values["filter_warnings"] = len(health)
    for _, value, threshold, line in health:
        state.write_event(Event("filter_inconsistent", metrics.last_t_s, value, threshold,
                                line))
        warnings.warn(line, FilterInconsistentWarning, stacklevel=2)
    recorder.write_finite(topics.METRICS, metrics.last_t_s, values)
    recorder.add_metadata("metrics", {"json": json.dumps(
        {k: (v if not isinstance(v, float) or np.isfinite(v) else None)
         for k, v in values.items()})})
    return values


RunState = _Run
"""The components and phases of one run, for a caller that drives the loop itself (the
Gymnasium environment :mod:`cosim.gym` steps it one control period at a time)."""

finish_run = _finish
"""Compute the run's metrics and write them to its log (the end of :func:`run`)."""
