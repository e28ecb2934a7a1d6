"""The multi-rate loop that runs one scenario, its observers looking on.

Clock at the physics step (``sim.physics_dt_s``); every period is a whole number of physics
steps (checked when the config is loaded). :meth:`_Run.advance` holds the order of a step's
phases (log, sense, control, actuate, disturb, advance the plant) and serves every way of
running: :func:`run` (with a log), :func:`run_unlogged` (without: no log observer, no
message built) and the Gymnasium environment (:mod:`cosim.gym`, which pauses it at each
control instant). Most steps have nothing due: the loop jumps from one step where
something is due to the next and the plant advances the steps between in one call
(:meth:`cosim.plant.car.MujocoPlant.advance_steps`, compiled C for the default plant): the
same steps in the same order, so the same numbers as one step at a time
(``tests/plant/test_compiled_steps.py``).

What only looks at the run is an observer (:mod:`cosim.simulation.observers`): the metrics
and monitors (:class:`cosim.simulation.watch.RunWatch`, whose terminal event ends the run)
and the log (:class:`cosim.simulation.run_log.RunLog`). A run that aborts (diverging
physics, an interrupt, an exception) still finishes its MCAP file, with ``completed:
false`` in its metrics.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from threadpoolctl import threadpool_limits

from cosim.core.config_fields import to_dict
from cosim.core.exceptions import PhysicsDivergenceError, TrackerFault
from cosim.core.records import Command, Estimate, VehicleState
from cosim.core.sensor_names import GNSS, RADAR
from cosim.log.piped_recorder import LogLink, PipedRecorder
from cosim.log.recorder import LiveSink, McapRecorder, NoLog, Recorder
from cosim.plant import disturbances
from cosim.plant.low_level import AccelToTorque
from cosim.plant.protocol import Plant
from cosim.simulation.belief_check import BeliefMismatchWarning, belief_mismatches
from cosim.simulation.course import Course, build_course
from cosim.simulation.estimator_port import EstimatorPort
from cosim.simulation.filter_health import FilterInconsistentWarning, filter_warnings
from cosim.simulation.metrics import MetricsAccumulator
from cosim.simulation.observers import LogInstant, RunObserver
from cosim.simulation.outcome import Event, OutcomeMonitor
from cosim.simulation.requirements import requirement_metrics
from cosim.simulation.run_control import StopRequest, WallClock, stop_on_signals
from cosim.simulation.run_log import RunLog
from cosim.simulation.scenario_config import ScenarioConfig, steps_per_period
from cosim.simulation.seeding import component_rng
from cosim.simulation.sensor_suite import SensorSuite
from cosim.simulation.traffic_log import TrafficLog
from cosim.simulation.traffic_loop import CollisionError, TrafficLoop, build_traffic
from cosim.simulation.watch import RunWatch
from cosim.simulation.workshop import Workshop
from estimation.protocol import Estimator
from tracker.paths.reference_path import ReferencePath
from tracker.protocol import Closable, Tracker

__all__ = ["RunResult", "RunState", "component_rng", "finish_run", "run", "run_unlogged",
           "scenario_course", "start_speed_resolved"]


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
    speed_mps = reference.speed_ref_at(s_m, 0.0)
    return dataclasses.replace(config, initial=dataclasses.replace(initial, speed_mps=speed_mps))


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
    """The simulation of one run (plant, sensors, filter, tracker, delay line,
    disturbances, traffic), its observers, and :meth:`advance`, the order of a step."""

    def __init__(self, config: ScenarioConfig, recorder: Recorder,
                 tracker: Tracker | None = None, workshop: Workshop | None = None) -> None:
        """``tracker``, if given, is the run's tracker; ``workshop`` keeps parts of earlier
        runs for this one (:mod:`cosim.simulation.workshop`; a new one: all built afresh).
        A recorder that keeps nothing (:class:`NoLog`) adds no log observer; one that
        keeps receives the header now."""
        workshop = workshop if workshop is not None else Workshop()
        self.clock = _Clock.from_config(config)
        self.course = scenario_course(config)
        self.course.reference.prepare_projection()  # built, if ever, before the clock starts
        config = start_speed_resolved(config, self.course.reference)
        self.config = config
        """The run's configuration, the start speed resolved (what the log records)."""
        traffic = build_traffic(config)
        self.plant: Plant = workshop.plant(config.plant, self.clock.dt_s, config.initial,
                                           traffic)
        self.filter = EstimatorPort(workshop.estimator(
            config.estimator, config.initial, config.tracker.model,
            component_rng(config.seed, "estimator.initial")))
        self.tracker: Tracker = tracker if tracker is not None else \
            workshop.tracker(config.tracker, config.manoeuvre, config.sim.control_period_s)
        """The run's tracker; the Gymnasium environment passes one that replays its actions."""
        self.low_level = AccelToTorque(config.tracker.model)
        self.sensors = SensorSuite(config, self.estimator.required_sensors, self.clock.dt_s)
        self.filter.localised = GNSS not in self.sensors.names
        self.delay_line: collections.deque[tuple[int, Command]] = collections.deque()
        self.yaw_rate_changes = collections.deque(disturbances.schedule(
            config.disturbances, self.clock.dt_s, component_rng(config.seed, "disturbances")))
        self._truth: VehicleState | None = None
        self.traffic = None if traffic is None else \
            TrafficLoop(config, self.plant, traffic, self.tracker,
                        component_rng(config.seed, f"sensors.{RADAR}"))
        """Traffic, range sensor, collisions, gap and ACC metrics
        (:mod:`cosim.simulation.traffic_loop`)."""
        self.watch = RunWatch(config, self.course, self.emit)
        """Metrics, outcome and course monitors; the terminal event the run stops at."""
        self.observers: tuple[RunObserver, ...] = (self.watch,)
        """Called at the points of each step, in this order (:mod:`.observers`)."""
        if recorder.keeps:
            log = RunLog(recorder, config, self.watch.metrics, self.sensors)
            traffic_log = None
            if self.traffic is not None:  # its messages: none built without a log
                traffic_log = TrafficLog(recorder, self.traffic.radar is not None,
                                         self.traffic.acc is not None)
                self.traffic.observers = (traffic_log,)
            log.header(self.course, self.plant.mjcf_xml, traffic_log)
            self.observers = (self.watch, log)

    @property
    def reference(self) -> ReferencePath:
        return self.course.reference

    @property
    def estimator(self) -> Estimator:
        return self.filter.estimator

    @property
    def metrics(self) -> MetricsAccumulator:
        return self.watch.metrics

    @property
    def monitor(self) -> OutcomeMonitor:
        return self.watch.monitor

    @property
    def stopped_by(self) -> Event | None:
        """The terminal event the run stops at (:data:`cosim.simulation.outcome.TERMINAL`),
        once it has happened."""
        return self.watch.stopped_by

    @property
    def truth(self) -> VehicleState:
        """The plant's true state now, read when first needed after a step (sensors and
        logging run every few physics steps; reading it after every step cost a sixth of
        the plant's time)."""
        if self._truth is None:
            self._truth = self.plant.state()
        return self._truth

    def current_estimate(self, t_s: float) -> Estimate:
        """The estimator predicted to ``t_s``, for the controller (:class:`EstimatorPort`)."""
        return self.filter.current(t_s)

    def emit(self, event: Event) -> None:
        """One event to every observer (the log writes it on ``/events``)."""
        for observer in self.observers:
            observer.event(event)

    def advance(self, k: int, *, observed: bool = False, pause_at_control: bool = False,
                stop: StopRequest | None = None,
                progress: Callable[[float], None] | None = None) -> tuple[int, bool]:
        """Run from physics step ``k``, taking the phases of each step at which something
        is due, in this order:

        1. *log*: at a log instant, the truth and the estimate (observed, not changed) to
           the observers; a terminal event they saw ends the run here;
        2. *sense*: the sensors due sample the truth, the filter fuses what they deliver;
           the run ends after this phase of its last step;
        3. *control*: at a control instant, the tracker plans from the filter predicted to
           now; its command enters the delay line (``plant.actuator_delay_s``);
        4. *actuate*: commands that come due leave the delay line; the low-level layer
           turns them into wheel torques with the controller's belief; the plant takes them;
        5. *disturb*: the unmeasured disturbances due are applied;
        6. the plant advances to the next step at which anything is due, in one call
           (:meth:`steps_to_next_due`, :meth:`MujocoPlant.advance_steps`).

        ``observed``: phases 1-2 of step ``k`` were taken already (a paused run resumes).
        ``pause_at_control``: return the step of the next control instant after its phases
        1-2 (the Gymnasium environment's agent acts there). Returns the step reached and
        whether the run has ended there.
        ``stop``: an interrupt asked for (:func:`stop_on_signals`) raises
        ``KeyboardInterrupt`` between steps. ``progress``: the fraction done, every 500
        physics steps."""
        clock = self.clock
        while True:
            if not observed:
                if not self._observe(k):
                    return k, True
                if pause_at_control and k % clock.control_steps == 0:
                    return k, False
            observed = False
            t_s = k * clock.dt_s
            if k % clock.control_steps == 0:
                self._control(k, t_s)
            self._actuate(k, t_s)
            self._disturb(k, t_s)
            n = self.steps_to_next_due(k)
            self.plant.advance_steps(n)
            self._truth = None
            if stop is not None and stop.signal_name:
                raise KeyboardInterrupt
            if progress is not None and (k + n) // 500 != k // 500:
                progress((k + n) // 500 * 500 / clock.n_steps)
            k += n

    def _observe(self, k: int) -> bool:
        """Phases 1-2 of step ``k``; False at the end of the run."""
        t_s = k * self.clock.dt_s
        if k % self.clock.log_steps == 0:
            self._log(k, t_s)
            if self.watch.stopped_by is not None:
                return False
        self._sense(k, t_s)
        return k < self.clock.n_steps

    def _log(self, k: int, t_s: float) -> None:
        """The estimate is predicted to the truth's own time stamp (the plant's clock, which
        the sensors stamp their measurements with too: ``t_s`` to a few 1e-18 s), so it is
        compared with the truth at the same instant, and the filter, predicting to the
        sensors' instant next, takes that prediction as made."""
        truth = self.truth
        forces = self.plant.tyre_forces()
        scene = k % self.clock.scene_steps == 0
        instant = LogInstant(k, t_s, truth, self.filter.observed(truth.t_s), scene,
                             None if forces is None else tuple(f.load_n for f in forces))
        for observer in self.observers:
            observer.logged(instant)
        if self.traffic is not None:
            self.traffic.log(t_s, truth, scene=scene)

    def _sense(self, k: int, t_s: float) -> None:
        if self.traffic is not None and self.traffic.radar_due(k):
            self.traffic.sense(t_s, self.truth)
        delivered = self.sensors.sample(k, self.truth)
        if not delivered:
            return
        if not self.filter.localised:
            self.filter.localised = any(m.sensor == GNSS for m in delivered)
        observers = self.observers
        for measurement in delivered:
            for observer in observers:
                observer.sensed(t_s, measurement)
        updates = self.filter.fuse(delivered)
        for measurement, update in zip(delivered, updates, strict=True):
            for observer in observers:
                observer.fused(t_s, measurement, update)

    def _control(self, k: int, t_s: float) -> None:
        estimate = self.filter.current(t_s)
        if self.filter.localised:
            # One timing scope for every tracker: the whole step (step_ms_*), not only the
            # solver call each tracker reports itself (solve_ms_*).
            start_s = time.perf_counter()
            command, plan = self.tracker.step(t_s, estimate, self.reference)
            step_time_s = time.perf_counter() - start_s
            for observer in self.observers:
                observer.controlled(t_s, plan, command, step_time_s)
        else:  # no fix yet: the controller waits, straight ahead at no acceleration
            command = Command(t_s=t_s, accel_mps2=0.0, steer_rad=0.0)
        self.delay_line.append((k + self.clock.delay_steps, command))
        # The filter drives its steering and its acceleration with the command from when
        # the software believes it reaches the actuator (tracker.latency_s, the belief of
        # the plant's delay).
        self.filter.command(t_s + self.config.tracker.latency_s, command.steer_rad,
                            command.accel_mps2)
        if self.traffic is not None:
            self.traffic.after_control(t_s)

    def _actuate(self, k: int, t_s: float) -> None:
        """Apply the commands that leave the delay line at step ``k``."""
        while self.delay_line and self.delay_line[0][0] <= k:
            _, command = self.delay_line.popleft()
            speed_mps = self.filter.observed(t_s)["vx_mps"]
            actuator = self.low_level.convert(command, speed_mps)
            self.plant.apply(actuator)
            for observer in self.observers:
                observer.actuated(t_s, command, actuator)

    def _disturb(self, k: int, t_s: float) -> None:
        """Apply the unmeasured disturbances due at step ``k`` (:mod:`cosim.plant.disturbances`)."""
        while self.yaw_rate_changes and self.yaw_rate_changes[0].step <= k:
            change = self.yaw_rate_changes.popleft()
            self.plant.add_yaw_rate(change.delta_radps)
            self._truth = None
            for observer in self.observers:
                observer.disturbed(t_s, change)

    def record_fault(self, error: TrackerFault) -> None:
        """The tracker's failure as an event of kind ``tracker_fault``: the one-line reason
        and the traceback of the user's code in ``detail`` (not an outcome event)."""
        self.emit(Event("tracker_fault", self.metrics.last_t_s, float("nan"), float("nan"),
                        f"{error}\n{error.detail}".strip()))

    def steps_to_next_due(self, k: int) -> int:
        """Physics steps from step ``k`` to the next step at which anything is due: a log
        entry, a sensor, the controller, a command leaving the delay line, a disturbance,
        the run's end, traffic's range sensor (the traffic cars' poses are set after every
        physics step by the plant itself)."""
        clock = self.clock
        due = clock.n_steps
        traffic = () if self.traffic is None else self.traffic.periods
        for period in (clock.log_steps, clock.control_steps, *self.sensors.steps, *traffic):
            due = min(due, (k // period + 1) * period)
        if self.delay_line:
            due = min(due, self.delay_line[0][0])
        if self.yaw_rate_changes:
            due = min(due, self.yaw_rate_changes[0].step)
        return max(due - k, 1)

    def loop(self, stop: StopRequest, progress: Callable[[float], None] | None) -> None:
        """The whole run (:meth:`advance` from step 0). ``progress(0.0)`` comes first: the
        run's signal handler is in place from then on."""
        if progress is not None:
            progress(0.0)
        self.advance(0, stop=stop, progress=progress)


def run(
    config: ScenarioConfig,
    out_path: Path,
    progress: Callable[[float], None] | None = None,
    live: LiveSink | None = None,
    workshop: Workshop | None = None,
    log_link: LogLink | None = None,
) -> RunResult:
    """Run one scenario to ``out_path``; ``progress`` is called with the fraction done;
    ``live`` is a second sink on the log's channels (``cosim run --live``); ``workshop``
    holds parts earlier runs built, for this one to reuse (:mod:`cosim.simulation.workshop`);
    ``log_link``, the pipes to a process that writes the log
    (:mod:`cosim.log.piped_recorder`: ``cosim run``'s parent), unless ``live`` is given.

    SIGINT and SIGTERM stop the run between two physics steps; the log is finished with
    ``completed: false`` and the result says ``interrupted``. A ``SystemExit`` (or another
    ``BaseException`` but ``KeyboardInterrupt``) raised by code inside the loop, a user's
    plug-in calling ``sys.exit``, ends the run the same way with outcome ``error`` and the
    reason; an ordinary exception is raised on once the log is finished.
    """
    wall_start = time.perf_counter()
    recorder: PipedRecorder | McapRecorder
    if log_link is not None and live is None:
        recorder = PipedRecorder(log_link, out_path, epoch_ns=config.sim.epoch_ns)
    else:
        recorder = McapRecorder(out_path, epoch_ns=config.sim.epoch_ns, live=live)
    with recorder:
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
        clock = WallClock(wall_start, time.perf_counter())  # set-up (and any build) ends
        try:
            # The run starts for real: the log takes its final name. Inside the try, so an
            # interrupt in the instant before the loop takes Ctrl-C over still finishes the
            # published log (completed: false) instead of leaving it without its metrics.
            recorder.publish()
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
            state.watch.collision(error.t_s, error.car)
        except KeyboardInterrupt:
            abort_reason = abort = "interrupted"
        except Exception as error:  # the log is finished below, then the error goes on
            _finish(state, clock, False,
                    f"{type(error).__name__}: {error}", "error")
            raise
        except BaseException as error:  # noqa: BLE001 - SystemExit from a user's plug-in
            abort_reason, abort = f"{type(error).__name__} raised during the run: " \
                f"{error}", "error"
        if progress is not None:
            progress(1.0)
        metrics = _finish(state, clock, completed, abort_reason, abort)
    return metrics, completed, abort_reason


def _finish(state: _Run, clock: WallClock, completed: bool, abort_reason: str,
            abort: str) -> dict[str, float | int | bool | str]:
    """The run's metrics (every key of :mod:`cosim.simulation.metric_keys`), the belief
    mismatches and filter warnings as events and warnings, all given to the observers."""
    watch = state.watch
    metrics = watch.metrics
    metrics.estimator_counts = state.filter.counts()
    setup_time_s, wall_time_s = clock.times()
    values: dict[str, float | int | bool | str] = dict(metrics.result(wall_time_s, completed))
    values["setup_time_s"] = setup_time_s
    values.update(watch.course_monitor.result())
    values["faults_injected"] = state.sensors.faults_injected()
    values["outcome"] = watch.monitor.outcome(abort)
    if state.traffic is not None:
        values.update(state.traffic.result())
    values.update(requirement_metrics(state.config.requirements, watch.signals,
                                      state.config.sim.log_period_s))
    values["events"] = len(watch.monitor.events)
    for event in watch.monitor.events:
        values.setdefault(f"{event.kind}_t_s", event.t_s)
    if abort_reason:
        values["abort_reason"] = abort_reason
    mismatches = belief_mismatches(values, to_dict(state.config))
    values["belief_mismatches"] = len(mismatches)
    for mismatch in mismatches:
        state.emit(Event("belief_mismatch", metrics.last_t_s, mismatch.nis, mismatch.bound,
                         mismatch.line))
        warnings.warn(mismatch.line, BeliefMismatchWarning, stacklevel=2)
    health = filter_warnings(values, {m.sensor for m in mismatches})
    values["filter_warnings"] = len(health)
    for _, value, threshold, line in health:
        state.emit(Event("filter_inconsistent", metrics.last_t_s, value, threshold, line))
        warnings.warn(line, FilterInconsistentWarning, stacklevel=2)
    for observer in state.observers:
        observer.finished(values)
    return values


RunState = _Run
"""The components and phases of one run, for a caller that drives the loop itself (the
Gymnasium environment :mod:`cosim.gym` steps it one control period at a time)."""

finish_run = _finish
"""Compute the run's metrics and write them to its log (the end of :func:`run`)."""
