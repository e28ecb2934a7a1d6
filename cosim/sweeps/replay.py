"""Replay a run's logged sensor stream into a fresh filter: one closed-loop run, many filters.

A run's log holds every measurement its sensors delivered (``/sensors/<name>``, after faults
and dropouts) and the truth at every log instant (``/vehicle/truth``). A filter that did not
steer the car, the same one with other beliefs say (its process noise scaled, for a test
that a mistuned filter fails), can be fed that stream as the runner fed the run's own
filter, step by step (:meth:`cosim.simulation.runner._Run.advance`): at a
log instant the estimate is looked at (``estimate_at``, which changes nothing), then the
measurements of that instant are fused (together where the filter can,
:class:`estimation.protocol.JointUpdater`), then at a control instant the filter is
predicted to it and told the command (steering and acceleration) the run's controller gave there
(``/control/command``, one per control instant in order, from ``tracker.latency_s`` later;
with ``plant.actuator_delay_s`` the commands of the run's last delay never reached the
actuator nor the log, and a replay's filter goes without them). Its initial estimate is
drawn from the run's seed as the runner draws it (``estimator.initial``), so a replay
with the run's own configuration repeats the run's filter, NEES and NIS alike.

What a replay does not repeat is the car: the controller saw the run's filter, not this
one, so the truth is the run's whatever the replayed filter believes. For a filter's
consistency that is no loss (its errors are judged against the truth the sensors saw), and
it makes a Monte Carlo of many filters cost one closed-loop run per seed.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim.core.records import Measurement
from cosim.core.sensor_names import FUSED_SENSORS
from cosim.log import topics
from cosim.log.reader import iter_topics
from cosim.simulation.estimator_port import EstimatorPort
from cosim.simulation.metrics import NEES_STATES
from cosim.simulation.runner import scenario_course, start_speed_resolved
from cosim.simulation.scenario_config import ScenarioConfig, steps_per_period
from cosim.simulation.seeding import component_rng
from cosim.simulation.workshop import Workshop
from cosim.sweeps.ensemble import EnsembleMember
from estimation.config import EstimatorConfig
from estimation.consistency import SETTLE_S
from estimation.protocol import ObservableEstimator
from estimation.update_result import GATE, PARTIAL
from tracker.paths.reference_path import wrap_angle

_NOT_VALUES = ("t_s", "sensor", "sigma")
"""Fields of a logged measurement that are not its channels."""


@dataclass(frozen=True)
class LoggedRun:
    """What a replay feeds a filter, read from a run's log in one pass
    (:func:`logged_run`)."""

    stream: dict[int, list[Measurement]]
    """The fused sensors' measurements by log time in nanoseconds, each instant's in the
    order the runner delivered them (its sensors' order). Null values (a non-finite
    channel) are NaN again; the covariance is diagonal from the logged sigmas."""
    truth: dict[int, np.ndarray]
    """The truth of :data:`NEES_STATES` by log time in nanoseconds."""
    commands: list[tuple[float, float]]
    """The commands (``/control/command``), ``(steer_rad, accel_mps2)`` in the order the
    controller gave them: the ``i``-th is the ``i``-th control instant's (the delay line is
    first in, first out)."""


def logged_run(path: Path) -> LoggedRun:
    """The sensor stream, the truth and the commands of the log at ``path``, in one pass
    over its records (reading a log is most of a replay's time that is not the filter's)."""
    wanted = ({topics.sensor_topic(name) for name in FUSED_SENSORS}
              | {topics.VEHICLE_TRUTH, topics.CONTROL_COMMAND})
    measurements: list[tuple[int, int, Measurement]] = []
    truth: dict[int, np.ndarray] = {}
    commands: list[tuple[float, float]] = []
    for topic, log_time_ns, message in iter_topics(Path(path), wanted):
        if topic == topics.VEHICLE_TRUTH:
            truth[log_time_ns] = np.array([message[name] for name in NEES_STATES], dtype=float)
            continue
        if topic == topics.CONTROL_COMMAND:
            commands.append((float(message["steer_rad"]), float(message["accel_mps2"])))
            continue
        names = tuple(k for k in message if k not in _NOT_VALUES)
        values = np.array([math.nan if message[n] is None else message[n] for n in names])
        covariance = np.diag(np.square(np.asarray(message["sigma"], dtype=float)))
        sensor = str(message["sensor"])
        measurements.append((log_time_ns, FUSED_SENSORS.index(sensor),
                             Measurement(sensor, float(message["t_s"]), names, values,
                                         covariance)))
    measurements.sort(key=lambda item: (item[0], item[1]))
    by_time: dict[int, list[Measurement]] = defaultdict(list)
    for log_time_ns, _, measurement in measurements:
        by_time[log_time_ns].append(measurement)
    return LoggedRun(dict(by_time), truth, commands)


def replay(config: ScenarioConfig, log: Path | LoggedRun,
           estimator: EstimatorConfig | None = None,
           workshop: Workshop | None = None) -> EnsembleMember:
    """The filter ``estimator`` (default: the run's own, ``config.estimator``) fed the
    sensor stream of the run of ``config`` logged at ``log`` (its path, or what
    :func:`logged_run` read from it, for many filters fed one log); its NEES at the run's log
    instants and its NIS per sensor, as :func:`cosim.sweeps.ensemble.run_member` gives them
    for the run's own filter (``metrics`` is empty: no car was driven). ``workshop`` lends
    the filter an earlier replay built, restarted (the same numbers as one built afresh)."""
    config = start_speed_resolved(config, scenario_course(config).reference)
    estimator = config.estimator if estimator is None else estimator
    workshop = workshop if workshop is not None else Workshop()
    filter_ = workshop.estimator(estimator, config.initial, config.tracker.model,
                                 component_rng(config.seed, "estimator.initial"))
    if not isinstance(filter_, ObservableEstimator):
        raise TypeError(f"estimator {estimator.name!r}: a replay needs estimate_at "
                        "(estimation.protocol.ObservableEstimator)")
    port = EstimatorPort(filter_)  # fused as the run fuses: together where it can
    logged = log if isinstance(log, LoggedRun) else logged_run(log)
    stream, truth, commands = logged.stream, logged.truth, iter(logged.commands)
    sim, dt_s = config.sim, config.sim.physics_dt_s
    log_steps = steps_per_period(sim.log_period_s, dt_s, "sim.log_period_s")
    control_steps = steps_per_period(sim.control_period_s, dt_s, "sim.control_period_s")
    n_steps = steps_per_period(sim.duration_s, dt_s, "sim.duration_s")
    sensor_steps = {round(t_ns * 1e-9 / dt_s) for t_ns in stream}
    yaw = NEES_STATES.index("yaw_rad")
    times, nees, normalized = [], [], []
    nis_sum: dict[str, float] = defaultdict(float)
    nis_dof: dict[str, int] = defaultdict(int)
    settled_sum: dict[str, float] = defaultdict(float)
    settled_dof: dict[str, int] = defaultdict(int)
    gated: dict[str, int] = defaultdict(int)
    for k in range(n_steps + 1):
        logs, controls = k % log_steps == 0, k % control_steps == 0
        if not (logs or controls or k in sensor_steps):
            continue
        t_s = k * dt_s
        t_ns = round(t_s * 1e9)
        if logs and t_ns in truth:
            estimate = filter_.estimate_at(t_s)
            error = np.array([estimate[name] for name in NEES_STATES]) - truth[t_ns]
            error[yaw] = float(wrap_angle(error[yaw]))
            covariance = estimate.sub_covariance(NEES_STATES)
            times.append(t_s)
            nees.append(float(error @ np.linalg.solve(covariance, error)))
            normalized.append(error**2 / np.diag(covariance))
        delivered = stream.get(t_ns, [])
        if delivered:
            results = port.fuse(delivered)
            for measurement, result in zip(delivered, results, strict=True):
                sensor, value, dim = measurement.sensor, result.joint_nis, result.joint_dim
                if dim == 0 or not np.isfinite(value):
                    continue
                nis_sum[sensor] += value
                nis_dof[sensor] += dim
                if measurement.t_s >= SETTLE_S:
                    settled_sum[sensor] += value
                    settled_dof[sensor] += dim
                else:
                    gated[sensor] += result.reason in (GATE, PARTIAL)
        if controls:
            filter_.predict(t_s)
            command = next(commands, None)
            if command is not None:
                port.command(t_s + config.tracker.latency_s, *command)
    by_state = np.array(normalized).reshape(-1, len(NEES_STATES)).T
    return EnsembleMember(config.seed, np.array(times), np.array(nees), dict(nis_sum),
                          dict(nis_dof), {}, dict(settled_sum), dict(settled_dof), dict(gated),
                          dict(zip(NEES_STATES, by_state, strict=True)))
