"""A run's log read back into typed arrays for the plots.

One pass over the MCAP file (plus the summary scan for metadata, metrics and truncation)
gives the truth, the estimate with its covariance, the applied commands, the tracker's
plans and the reference path. Tracking errors are computed as the metrics compute them: the
true centre of gravity projected onto the reference path (``ReferencePath.project``, the
path rebuilt from the logged samples), heading error wrapped to (-pi, pi], speed error as
the true horizontal speed minus the reference speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.core.exceptions import CosimError, LogReadError
from cosim.log import topics
from cosim.log.reader import iter_topics, log_file_problem, read_summary
from cosim.simulation.changes import (
    config_changes,
    config_differences,
    flat_config,
    mismatch_first,
    shown_difference,
)
from cosim.simulation.metrics import NEES_STATES
from tracker.paths.reference_path import ReferencePath, wrap_angle

TOPICS = {topics.VEHICLE_TRUTH, topics.VEHICLE_ESTIMATE, topics.CONTROL_COMMAND,
          topics.CONTROL_PLAN, topics.REFERENCE_PATH, topics.ESTIMATOR_UPDATES,
          topics.CONTROL_ERRORS}

TRUTH_FIELDS = ("x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "yaw_rate_radps", "ax_mps2",
                "steer_rad", "roll_rad")
"""The ``/vehicle/truth`` fields of the car's state an estimate's state of the same name is
compared with."""
BIAS_FIELDS = ("gyro_bias_radps", "ax_bias_mps2", "ay_bias_mps2")
"""The IMU's true biases, in ``/vehicle/truth`` when the run has an IMU (NaN otherwise)."""
ANGLES = ("yaw_rad", "roll_rad")
"""Errors wrapped to (-pi, pi]."""


@dataclass(frozen=True)
class Truth:
    """``/vehicle/truth``: the true state at each log time (world frame, SI)."""

    log_time_ns: np.ndarray
    t_s: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    yaw_rad: np.ndarray
    vx_mps: np.ndarray
    vy_mps: np.ndarray
    yaw_rate_radps: np.ndarray
    ax_mps2: np.ndarray
    steer_rad: np.ndarray
    """Road-wheel angle of the front axle (the steering actuator's output)."""
    roll_rad: np.ndarray
    gyro_bias_radps: np.ndarray
    ax_bias_mps2: np.ndarray
    ay_bias_mps2: np.ndarray
    """The IMU's true biases (NaN when the log has none: no IMU, or an older log)."""

    @property
    def speed_mps(self) -> np.ndarray:
        return np.hypot(self.vx_mps, self.vy_mps)


@dataclass(frozen=True)
class EstimateLog:
    """``/vehicle/estimate``: the filter's mean and covariance over ``state_names``."""

    log_time_ns: np.ndarray
    t_s: np.ndarray
    state_names: tuple[str, ...]
    mean: np.ndarray
    """Shape (samples, states)."""
    covariance: np.ndarray
    """Shape (samples, states, states)."""

    def column(self, name: str) -> np.ndarray:
        return self.mean[:, self.state_names.index(name)]

    def sigma(self, name: str) -> np.ndarray:
        i = self.state_names.index(name)
        return np.sqrt(np.clip(self.covariance[:, i, i], 0.0, None))


@dataclass(frozen=True)
class Commands:
    """``/control/command``: the commands as applied to the plant (after the delay line)."""

    t_s: np.ndarray
    accel_mps2: np.ndarray
    steer_rad: np.ndarray


@dataclass(frozen=True)
class Plans:
    """``/control/plan``: one entry per control step."""

    t_s: np.ndarray
    dt_s: np.ndarray
    solve_time_s: np.ndarray
    status: tuple[str, ...]
    success: np.ndarray
    fallback: np.ndarray
    predicted: tuple[dict[str, np.ndarray], ...]
    """Per plan, each predicted state and input over the horizon, by name (no prefix)."""

    @property
    def has_positions(self) -> bool:
        """Whether the plans predict world-frame ``x_m`` and ``y_m`` (not every MPC's
        states do: dynamic-mpc predicts path errors)."""
        return bool(self.predicted) and {"x_m", "y_m"} <= set(self.predicted[0])

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(self.predicted[0]) if self.predicted else ()


@dataclass(frozen=True)
class Reference:
    """``/reference/path`` and the path rebuilt from it."""

    x_m: np.ndarray
    y_m: np.ndarray
    speed_mps: float
    path: ReferencePath


@dataclass(frozen=True)
class TrackingErrors:
    """Truth against the reference at each truth sample."""

    t_s: np.ndarray
    s_m: np.ndarray
    """Arc length of the projection of the CoG onto the path."""
    cte_m: np.ndarray
    """Signed lateral error, positive left of the path."""
    heading_err_rad: np.ndarray
    speed_err_mps: np.ndarray
    ref_speed_mps: np.ndarray
    """The reference speed at each sample: the logged profile (``/control/errors``) where
    the log has it, else the path's constant speed."""


@dataclass(frozen=True)
class EstimationErrors:
    """Estimate minus truth at the log times both have."""

    t_s: np.ndarray
    error: dict[str, np.ndarray]
    """Per state in both truth and estimate (yaw wrapped)."""
    sigma: dict[str, np.ndarray]
    nees: np.ndarray | None
    """Per-sample NEES over ``nees_states`` (None when the covariance is singular, e.g. the
    `truth` estimator)."""
    nees_states: tuple[str, ...]


@dataclass(frozen=True)
class SensorNis:
    """``/estimator/updates`` of one sensor: NIS per degree of freedom of each update the
    filter tested (accepted or gated)."""

    t_s: np.ndarray
    nis_per_dof: np.ndarray
    accepted: np.ndarray


@dataclass(frozen=True)
class RunLog:
    """Everything the plots need from one log."""

    path: Path
    label: str
    config: dict[str, Any]
    metrics: dict[str, Any] | None
    truncated: bool
    truth: Truth
    estimate: EstimateLog | None
    commands: Commands | None
    plans: Plans | None
    reference: Reference | None
    tracking: TrackingErrors | None
    estimation: EstimationErrors | None
    nis: dict[str, SensorNis] | None = None
    """Per sensor; None for logs without ``/estimator/updates``."""
    changes: tuple[str, ...] = ()
    """What the run changed from its scenario (``plant.mass_kg=2000``;
    :func:`cosim.simulation.changes.config_changes`)."""

    @property
    def tracker_name(self) -> str:
        return str(self.config.get("tracker", {}).get("name", "?"))

    @property
    def scenario_name(self) -> str:
        return str(self.config.get("name", self.path.stem))


def _floats(values: list[Any]) -> np.ndarray:
    return np.array([math.nan if v is None else float(v) for v in values], dtype=float)


def _column(messages: list[tuple[int, dict[str, Any]]], name: str) -> np.ndarray:
    return _floats([m.get(name) for _, m in messages])


def _truth(messages: list[tuple[int, dict[str, Any]]]) -> Truth:
    return Truth(
        log_time_ns=np.array([t for t, _ in messages], dtype=np.int64),
        **{name: _column(messages, name)
           for name in ("t_s", *TRUTH_FIELDS, *BIAS_FIELDS)},
    )


def _estimate(messages: list[tuple[int, dict[str, Any]]]) -> EstimateLog | None:
    if not messages:
        return None
    names = tuple(messages[0][1]["state_names"])
    messages = [(t, m) for t, m in messages if tuple(m["state_names"]) == names]
    k = len(names)
    covariance = np.array([_floats(m["covariance"]) for _, m in messages]).reshape(-1, k, k)
    return EstimateLog(
        log_time_ns=np.array([t for t, _ in messages], dtype=np.int64),
        t_s=_column(messages, "t_s"),
        state_names=names,
        mean=np.array([[math.nan if m.get(n) is None else m[n] for n in names]
                       for _, m in messages], dtype=float),
        covariance=covariance,
    )


def _commands(messages: list[tuple[int, dict[str, Any]]]) -> Commands | None:
    if not messages:
        return None
    return Commands(*(_column(messages, n) for n in ("t_s", "accel_mps2", "steer_rad")))


def _plans(messages: list[tuple[int, dict[str, Any]]]) -> Plans | None:
    if not messages:
        return None
    predicted = tuple(
        {key.removeprefix("predicted_"): _floats(value) for key, value in m.items()
         if key.startswith("predicted_") and isinstance(value, list)}
        for _, m in messages)
    return Plans(
        t_s=_column(messages, "t_s"),
        dt_s=_column(messages, "dt_s"),
        solve_time_s=_column(messages, "solve_time_s"),
        status=tuple(str(m.get("status", "?")) for _, m in messages),
        success=np.array([bool(m.get("success", True)) for _, m in messages]),
        fallback=np.array([bool(m.get("fallback", False)) for _, m in messages]),
        predicted=predicted,
    )


def _reference(messages: list[tuple[int, dict[str, Any]]]) -> Reference | None:
    if not messages:
        return None
    message = messages[0][1]
    x, y = _floats(message["x_m"]), _floats(message["y_m"])
    try:
        path = ReferencePath(x, y, float(message["speed_mps"]),
                             closed=bool(message.get("closed", False)))
    except CosimError:
        return None
    return Reference(x, y, float(message["speed_mps"]), path)


def _tracking(truth: Truth, reference: Reference | None,
              errors: list[tuple[int, dict[str, Any]]]) -> TrackingErrors | None:
    if reference is None:
        return None
    ref_speed = np.full(truth.t_s.shape, reference.speed_mps)
    logged = {time_ns: m.get("ref_speed_mps") for time_ns, m in errors}
    for i, time_ns in enumerate(truth.log_time_ns):
        value = logged.get(int(time_ns))
        if value is not None:
            ref_speed[i] = float(value)
    projections = [reference.path.project(x, y) for x, y in zip(truth.x_m, truth.y_m,
                                                                  strict=True)]
    path_yaw = np.array([p.path_yaw_rad for p in projections])
    return TrackingErrors(
        t_s=truth.t_s,
        s_m=np.array([p.s_m for p in projections]),
        cte_m=np.array([p.lateral_error_m for p in projections]),
        heading_err_rad=np.asarray(wrap_angle(truth.yaw_rad - path_yaw)),
        speed_err_mps=truth.speed_mps - ref_speed,
        ref_speed_mps=ref_speed,
    )


def _estimation(truth: Truth, estimate: EstimateLog | None) -> EstimationErrors | None:
    if estimate is None:
        return None
    common_ns, in_truth, in_estimate = np.intersect1d(
        truth.log_time_ns, estimate.log_time_ns, assume_unique=False, return_indices=True)
    if common_ns.size == 0:
        return None
    errors: dict[str, np.ndarray] = {}
    sigmas: dict[str, np.ndarray] = {}
    for name in (*TRUTH_FIELDS, *BIAS_FIELDS):
        if name not in estimate.state_names or not np.any(np.isfinite(getattr(truth, name))):
            continue
        error = estimate.column(name)[in_estimate] - getattr(truth, name)[in_truth]
        errors[name] = np.asarray(wrap_angle(error)) if name in ANGLES else error
        sigmas[name] = estimate.sigma(name)[in_estimate]
    nees_states = tuple(n for n in NEES_STATES if n in errors)
    nees = None
    if nees_states:
        idx = [estimate.state_names.index(n) for n in nees_states]
        block = estimate.covariance[np.ix_(in_estimate, idx, idx)]
        stacked = np.stack([errors[n] for n in nees_states], axis=1)
        usable = np.all(np.isfinite(block), axis=(1, 2)) & np.all(np.isfinite(stacked), axis=1)
        usable[usable] &= np.linalg.det(block[usable]) > 0.0
        if np.any(usable):
            nees = np.full(common_ns.size, math.nan)
            nees[usable] = np.einsum("ni,ni->n", stacked[usable],
                                     np.linalg.solve(block[usable],
                                                     stacked[usable][..., None])[..., 0])
    return EstimationErrors(truth.t_s[in_truth], errors, sigmas, nees, nees_states)


def load_run(path: Path | str) -> RunLog:
    """Read a log for plotting (a truncated log gives what it holds)."""
    path = Path(path)
    problem = log_file_problem(path)
    if problem is not None:
        raise CosimError(f"{str(path)!r}: {problem} (expected an MCAP log)")
    summary = read_summary(path)
    messages: dict[str, list[tuple[int, dict[str, Any]]]] = {topic: [] for topic in TOPICS}
    for topic, log_time_ns, message in iter_topics(path, TOPICS):
        messages[topic].append((log_time_ns, message))
    if not messages[topics.VEHICLE_TRUTH]:
        raise LogReadError(f"{str(path)!r}: no /vehicle/truth messages (nothing to plot)")
    truth = _truth(messages[topics.VEHICLE_TRUTH])
    if not np.any(np.isfinite(truth.t_s) & np.isfinite(truth.x_m) & np.isfinite(truth.y_m)):
        raise LogReadError(f"{str(path)!r}: no /vehicle/truth message with a finite t_s, x_m "
                           "and y_m (nothing to plot): expected a log that cosim wrote")
    estimate = _estimate(messages[topics.VEHICLE_ESTIMATE])
    reference = _reference(messages[topics.REFERENCE_PATH])
    config = summary.config
    label = f"{config.get('name', path.stem)} / {config.get('tracker', {}).get('name', '?')}"
    return RunLog(
        path=path, label=label, config=config, metrics=summary.metrics,
        truncated=summary.truncated, truth=truth, estimate=estimate,
        commands=_commands(messages[topics.CONTROL_COMMAND]),
        plans=_plans(messages[topics.CONTROL_PLAN]), reference=reference,
        tracking=_tracking(truth, reference, messages[topics.CONTROL_ERRORS]),
        estimation=_estimation(truth, estimate),
        nis=_nis(messages[topics.ESTIMATOR_UPDATES]),
        changes=tuple(config_changes(config)) if config else (),
    )


def _nis(messages: list[tuple[int, dict[str, Any]]]) -> dict[str, SensorNis] | None:
    if not messages:
        return None
    by_sensor: dict[str, list[dict[str, Any]]] = {}
    for _, message in messages:
        if message.get("nis") is not None and message.get("dof", 0) > 0:
            by_sensor.setdefault(str(message["sensor"]), []).append(message)
    return {sensor: SensorNis(
        t_s=np.array([m["t_s"] for m in items], dtype=float),
        nis_per_dof=np.array([m["nis"] / m["dof"] for m in items], dtype=float),
        accepted=np.array([bool(m["accepted"]) for m in items]),
    ) for sensor, items in sorted(by_sensor.items())}


LABEL_DIFFERENCES_A_LINE = 3
"""A run's label names every configuration difference, this many a line."""


def load_estimation(path: Path | str) -> EstimationErrors | None:
    """The estimation errors of a log (and their NEES) alone: reads only the truth and the
    estimate, for ensembles of many runs (:mod:`cosim.sweeps.ensemble`)."""
    wanted = (topics.VEHICLE_TRUTH, topics.VEHICLE_ESTIMATE)
    messages: dict[str, list[tuple[int, dict[str, Any]]]] = {topic: [] for topic in wanted}
    for topic, log_time_ns, message in iter_topics(Path(path), set(wanted)):
        messages[topic].append((log_time_ns, message))
    if not messages[topics.VEHICLE_TRUTH]:
        raise LogReadError(f"{str(path)!r}: no /vehicle/truth messages")
    return _estimation(_truth(messages[topics.VEHICLE_TRUTH]),
                       _estimate(messages[topics.VEHICLE_ESTIMATE]))


def distinct_labels(runs: list[RunLog]) -> list[RunLog]:
    """The runs with labels that tell them apart: by what differs in their logged
    configurations (``plant.mass_kg=1575`` against ``plant.mass_kg=2000``; runs that share
    a configuration get their file name too), else by file name, else by number."""
    from dataclasses import replace

    if len(runs) < 2:
        return runs
    # The scenario and the tracker are in every label already.
    # Every difference, never "+n more" (the one hidden could be the cause), the two sides
    # of a model mismatch first.
    differing = mismatch_first([key for key in config_differences([run.config for run in runs])
                                if key not in ("name", "tracker.name")])
    if differing:
        labelled = []
        for run in runs:
            flat = flat_config(run.config)
            parts = [shown_difference(key, flat) for key in differing]
            lines = [", ".join(parts[i:i + LABEL_DIFFERENCES_A_LINE])
                     for i in range(0, len(parts), LABEL_DIFFERENCES_A_LINE)]
            labelled.append(replace(run, label=f"{run.label}: " + ",\n  ".join(lines)))
        if len({run.label for run in labelled}) == len(labelled):
            return labelled
        alike = [sum(other.label == run.label for other in labelled) > 1 for run in labelled]
        stems = [run.path.stem for run, shared in zip(labelled, alike, strict=True) if shared]
        if len(set(stems)) == len(stems):  # some runs share a configuration: add the file
            return [replace(run, label=f"{run.label} ({run.path.stem})") if shared else run
                    for run, shared in zip(labelled, alike, strict=True)]
    labels = [run.label for run in runs]
    if len(set(labels)) == len(labels):
        return runs
    estimators = [str(run.config.get("estimator", {}).get("name", "?")) for run in runs]
    if len(set(estimators)) == len(estimators):
        return [replace(run, label=f"{run.label} + {e}") for run, e in zip(runs, estimators,
                                                                            strict=True)]
    stems = [run.path.stem for run in runs]
    if len(set(stems)) == len(stems):
        return [replace(run, label=f"{run.label} ({run.path.stem})") for run in runs]
    return [replace(run, label=f"run {n}: {run.label}") for n, run in enumerate(runs, 1)]
