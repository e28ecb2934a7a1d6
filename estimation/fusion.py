"""Asynchronous multi-rate fusion with per-channel gating: what every Kalman filter here shares.

:class:`KalmanFusion` holds everything about *when* and *whether* a measurement is fused;
its subclasses (:class:`estimation.ekf.Ekf`, :class:`estimation.ukf.Ukf`) say *how*, with
filterpy's filters and the models of :mod:`estimation.process_model` and
:mod:`estimation.measurement_models`:

- time: every measurement is fused at its own time stamp; the filter predicts to it in
  sub-steps of at most ``config.max_step_s`` and refuses to go back;
- per-measurement checks: non-finite values are rejected (never fused), stale measurements
  (older than the filter) are rejected, the normalised innovation squared (NIS) is tested
  against a chi-square gate, jointly and, if that fails, channel by channel; a channel that
  fails for ``gate_release_s`` is believed again (its jump is given room in P first);
  every outcome is counted per sensor;
- hygiene: yaw wrapped to (-pi, pi], angle innovations wrapped, P kept symmetric, and an
  update that would leave P not positive definite or anything non-finite is undone.

A subclass implements :meth:`KalmanFusion._predict_one` (one sub-step of the prediction) and
:meth:`KalmanFusion._trial_update` (the filter's update of a group of channels, computed
and then undone, so that the gate can look at it first) and keeps its mean and covariance
in :attr:`KalmanFusion._x` / :attr:`KalmanFusion._p`.
"""

from __future__ import annotations

import dataclasses
import math
from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

from cosim.core.dense_function import DenseFunction
from cosim.core.exceptions import ConfigError
from cosim.core.initial_state import InitialState
from cosim.core.records import Estimate, Measurement
from cosim.core.sensor_names import FUSED_SENSORS, GNSS
from cosim.core.vehicle_params import VehicleParams
from estimation.accel_commands import AccelCommands, DriveBelief
from estimation.belief_models import bicycle_params, process_noise, told_process_noise
from estimation.compiled_models import recipe, recorded, use_compiled
from estimation.config import EstimatorConfig
from estimation.consistency import chi_square_quantile
from estimation.covariance_room import first_fix, room_for_jump, room_for_surprise
from estimation.errors import EstimatorError
from estimation.history import FusionState, Lookahead
from estimation.initial import initial_belief
from estimation.innovation import (
    CheckedMeasurement,
    Innovation,
    Selection,
    TrialUpdate,
    block_nis,
    normalised_innovation_squared,
    residual_function,
)
from estimation.joint_update import JointPosterior
from estimation.measurement_models import MeasurementModel, build_measurement_models
from estimation.process_model import MAX_STEP_S, ProcessModel
from estimation.state import ANGLE_STATES, STATE_NAMES, state_index, wrap_angle
from estimation.steering_commands import SteeringCommands
from estimation.steering_model import SteeringBelief
from estimation.timing import forward_interval_s, is_stale
from estimation.update_order import linear_first
from estimation.update_result import (
    ACCEPTED,
    GATE,
    GATE_RELEASED,
    IGNORED,
    INVALID,
    NON_FINITE,
    PARTIAL,
    STALE,
    SensorCounts,
    UpdateResult,
)


class KalmanFusion(ABC):
    """A Kalman filter over :data:`estimation.state.STATE_NAMES`, fed asynchronously.

    ``initial`` is the car's initial state and ``config`` the prior's standard deviations;
    the mean is drawn around ``initial`` with ``rng`` as ``config.initial`` says
    (:func:`estimation.initial.initial_belief`). ``belief`` gives the dynamic bicycle, the
    wheel radius and the track the models need. ``t0_s`` is the time of the initial belief.

    The measurement noise ``R`` of every update is the filter's own belief
    (``config.noise``, :mod:`estimation.noise_config`) plus the model's error
    (``model_sigma``); the covariance a measurement carries is the sensor's truth, which
    a real filter cannot know, and is not used.
    """

    required_sensors: tuple[str, ...] = (GNSS,)
    """Sensors without which the filter cannot work (GNSS alone makes every vehicle state
    observable)."""

    supported_sensors: tuple[str, ...] = FUSED_SENSORS
    """Sensors the filter fuses; measurements of any other sensor are ignored."""

    state_names: tuple[str, ...] = STATE_NAMES

    kind: str = ""
    """Short name for messages ("EKF", "UKF")."""

    def __init__(self, config: EstimatorConfig, initial: InitialState, belief: VehicleParams,
                 *, t0_s: float = 0.0, rng: np.random.Generator | None = None) -> None:
        if not 0.0 < config.max_step_s <= MAX_STEP_S:
            raise ConfigError(f"estimator.max_step_s = {config.max_step_s!r}: expected a "
                              f"number in (0, {MAX_STEP_S:g}]")
        self._config = config
        bicycle = bicycle_params(config, belief)
        self._untold_noise = process_noise(config)
        """The process noise before the first command (:func:`told_process_noise`)."""
        self._steering = SteeringBelief.from_vehicle(belief, config.steering_compliance_radpnm)
        # The library an earlier process kept for this recipe gives the functions it holds
        # without their graphs being built (estimation.compiled_models.recorded).
        formula = recipe(type(self), config, belief)
        self._recorded_library = recorded(self.kind, formula) if config.compiled else None
        self._process = ProcessModel(
            self._untold_noise, bicycle, config.lateral_residual_time_constant_s,
            sigma_point_count=self._sigma_point_count(), steering=self._steering,
            library=self._recorded_library)
        self._commands = SteeringCommands()
        """The steering commands told (:meth:`command`), which the predictions run along."""
        self._accel_commands = AccelCommands(DriveBelief(
            config.accel_command_time_constant_s, config.accel_command_relative_sigma))
        """The acceleration commands told (:meth:`accel_command`), an input of the same."""
        self._ax, self._drag = state_index("ax_mps2"), config.accel_command_cornering_drag
        self._models: dict[str, MeasurementModel] = build_measurement_models(
            belief,
            wheel_model_sigma_mps=config.wheel_model_sigma_mps,
            lateral_accel_model_sigma_mps2=config.lateral_accel_model_sigma_mps2,
            steer_model_sigma_rad=config.steer_model_sigma_rad,
            bicycle=bicycle,
            wheel_slip_per_force_ratio=config.wheel_slip_per_force_ratio,
            wheel_slip_combined_stiffness_1prad=config.wheel_slip_combined_stiffness_1prad,
            wheel_slip_saturation=(config.wheel_slip_peak_force_ratio, config.wheel_slip_shape,
                                   config.wheel_slip_curvature),
            tyre_vertical_compliance_mpn=config.tyre_vertical_compliance_mpn,
        )
        if config.compiled:
            use_compiled(self.kind, self._hot_functions(), formula)
        self._angle_indices = tuple(state_index(name) for name in ANGLE_STATES)
        self._noise_variances = config.noise.channel_variances()
        self._gate_thresholds: dict[int, float] = {}
        self._selections: dict[tuple[str, tuple[str, ...]], Selection] = {}
        self.restart(initial, t0_s=t0_s, rng=rng)

    def restart(self, initial: InitialState, *, t0_s: float = 0.0,
                rng: np.random.Generator | None = None) -> None:
        """Start again from the initial belief drawn around ``initial`` with ``rng`` at
        ``t0_s``: every count, gate timer and prediction forgotten, the models (and their
        compiled C) kept. A restarted filter runs bit for bit as a newly built one
        (:class:`estimation.protocol.Restartable`); the gate thresholds and channel
        selections it keeps depend on the configuration only."""
        if not math.isfinite(t0_s):
            raise ValueError(f"t0_s = {t0_s!r}: expected a finite time")
        mean, covariance = initial_belief(self._config, initial, rng)
        self._setup_filter(mean, covariance)
        self._t_s = float(t0_s)
        self._awaiting_first_fix = self._config.initial == "first-fix"
        self._counts: dict[str, SensorCounts] = {}
        self._gate_failing_since_s: dict[tuple[str, tuple[str, ...]], float] = {}
        self._lookahead: Lookahead | None = None
        self._commands.clear()
        self._accel_commands.clear()
        self._process.use_noise(self._untold_noise)

    # ------------------------------------------------------------------- filter-specific

    def _sigma_point_count(self) -> int:
        """Sigma points the process model should be mapped over (0: none)."""
        return 0

    @abstractmethod
    def _setup_filter(self, mean: np.ndarray, covariance: np.ndarray) -> None:
        """Set up the filter (its mean, covariance, filterpy object) with this initial belief."""

    @property
    @abstractmethod
    def _x(self) -> np.ndarray:
        """The mean, 1-D (a view: do not modify in place)."""

    @abstractmethod
    def _set_mean(self, mean: np.ndarray) -> None: ...

    @property
    @abstractmethod
    def _p(self) -> np.ndarray:
        """The covariance (a view: do not modify in place)."""

    @abstractmethod
    def _set_covariance(self, covariance: np.ndarray) -> None: ...

    @abstractmethod
    def _predict_one(self, t0_s: float, t1_s: float, dt_s: float,
                     command_rad: float | None) -> None:
        """Propagate mean and covariance over one sub-step from ``t0_s`` to ``t1_s``
        (``dt_s`` long, at most ``max_step_s``), the steering driven by ``command_rad``
        (None: no command told yet): the acceleration moved by its commands
        (:meth:`_follow_accel_command`), the process model's sub-step, the angles wrapped
        and the covariance symmetrised (:meth:`_normalise`)."""

    @abstractmethod
    def _trial_update(
        self,
        model: MeasurementModel,
        rows: tuple[int, ...],
        z: np.ndarray,
        r_matrix: np.ndarray,
        residual: Callable[[np.ndarray, np.ndarray], np.ndarray],
        angle_rows: tuple[int, ...],
    ) -> TrialUpdate:
        """The filter's update with the channels ``rows`` of ``model`` (measured ``z``,
        noise ``r_matrix``), computed without changing the belief."""

    # ----------------------------------------------------------------------------- queries

    @property
    def t_s(self) -> float:
        """Time of the current belief."""
        return self._t_s

    def estimate(self) -> Estimate:
        """The current belief (copies: later steps do not change it)."""
        return Estimate(
            t_s=self._t_s,
            names=STATE_NAMES,
            mean=np.array(self._x, dtype=float).reshape(-1),
            covariance=np.array(self._p, dtype=float),
        )

    def estimate_at(self, t_s: float) -> Estimate:
        """The belief predicted to ``t_s``, leaving the filter as it was.

        For observers (the log, the metrics): the prediction runs on the filter and is then
        undone (mean, covariance and time restored exactly), so the filter's own sequence of
        predictions, and with it every later estimate, is the same whether or not, and how
        often, anyone looks.
        """
        mean, covariance, t0_s = self._x.copy(), self._p.copy(), self._t_s
        predicted = None
        try:
            self.predict(t_s)
            predicted = self._x, self._p, self._t_s
            return self.estimate()
        finally:
            self._set_mean(mean)
            self._set_covariance(covariance)
            self._t_s = t0_s
            self._lookahead = None if predicted is None else Lookahead(
                (self._x, self._p), t0_s, predicted[2], predicted[0], predicted[1])

    def state(self) -> FusionState:
        """Everything that changes as the filter runs (:mod:`estimation.history`)."""
        return FusionState(self._t_s, self._x.copy(order="K"), self._p.copy(order="K"),
                           {s: dataclasses.replace(c) for s, c in self._counts.items()},
                           dict(self._gate_failing_since_s), self._awaiting_first_fix)

    def restore(self, state: FusionState) -> None:
        """Continue from ``state`` (:meth:`state`) as the filter would have from there."""
        self._set_mean(state.mean.copy(order="K"))
        self._set_covariance(state.covariance.copy(order="K"))
        self._t_s = state.t_s
        self._counts = {s: dataclasses.replace(c) for s, c in state.counts.items()}
        self._gate_failing_since_s = dict(state.gate_failing_since_s)
        self._awaiting_first_fix = state.awaiting_first_fix
        self._lookahead = None

    def counts(self) -> dict[str, dict[str, int]]:
        """Per sensor: accepted, rejected (by cause), ignored and gate-released updates."""
        return {sensor: dataclasses.asdict(c) for sensor, c in sorted(self._counts.items())}

    def gate_threshold(self, dim: int) -> float:
        """The NIS above which a ``dim``-channel update is rejected (chi-square quantile)."""
        if dim not in self._gate_thresholds:
            if dim < 1:
                raise ValueError(f"dim = {dim}: expected at least one channel")
            self._gate_thresholds[dim] = chi_square_quantile(self._config.gate_probability, dim)
        return self._gate_thresholds[dim]

    def _hot_functions(self) -> tuple[DenseFunction, ...]:
        """The model functions this filter evaluates at every step, compiled to C with
        ``estimator.compiled`` (none by default)."""
        return ()

    # ----------------------------------------------------------------------------- predict

    def predict(self, t_s: float) -> None:
        """Propagate the belief to ``t_s`` (no-op at the current time; never backwards).

        A prediction an observer made from this very belief to ``t_s`` (:meth:`estimate_at`)
        is taken as it was: the same arithmetic, done once.
        """
        interval_s = forward_interval_s(self._t_s, float(t_s), "filter")
        if interval_s == 0.0:
            return
        lookahead, self._lookahead = self._lookahead, None
        if (lookahead is not None and lookahead.t_s == float(t_s)
                and lookahead.t0_s == self._t_s and lookahead.before[0] is self._x
                and lookahead.before[1] is self._p):
            self._set_mean(lookahead.mean)
            self._set_covariance(lookahead.covariance)
            self._t_s = lookahead.t_s
            return
        start_s = self._t_s
        for piece_s, command_rad in self._commands.pieces(self._t_s, float(t_s), interval_s):
            substeps = max(1, math.ceil(piece_s / self._config.max_step_s - 1e-9))
            dt_s = piece_s / substeps
            for k in range(substeps):
                self._predict_one(start_s + k * dt_s, start_s + (k + 1) * dt_s, dt_s,
                                  command_rad)
            start_s += piece_s
        self._t_s = float(t_s)
        if not (np.isfinite(self._x).all() and np.isfinite(self._p).all()):
            raise EstimatorError(f"{self.kind} prediction to t_s = {t_s} s produced a "
                                 "non-finite state or covariance")

    def command(self, t_s: float, steer_rad: float) -> None:
        """The steering command ``steer_rad`` acts on the actuator from ``t_s`` on (the
        controller's command, at the time the software believes it reaches the actuator):
        from then on the predictions drive the steering states with it
        (:mod:`estimation.steering_model`). ``t_s`` must not be before the filter's time
        nor the last command's."""
        first = not self._commands.told
        self._commands.add(t_s, steer_rad, not_before_s=self._t_s)
        if first:  # the steering's noise is what the commands do not explain
            self._use_told_noise()
        self._lookahead = None  # a prediction made before it may have run past t_s

    def accel_command(self, t_s: float, accel_mps2: float) -> None:
        """The acceleration command ``accel_mps2`` acts on the drive from ``t_s`` on (as
        :meth:`command`): the predictions move the acceleration with it, plus the cornering
        drag at the estimate now (``estimator.accel_command_cornering_drag``; the drag is an
        input, :mod:`estimation.accel_commands`), unless ``estimator.accel_commands`` is off."""
        if self._config.accel_commands:
            first = not self._accel_commands.told
            drag = self._process.cornering_drag_mps2(self._x) if self._drag else 0.0
            self._accel_commands.add(t_s, accel_mps2 + drag, not_before_s=self._t_s)
            if first:  # the jerk is the commands' no longer
                self._use_told_noise()
            self._lookahead = None

    def _use_told_noise(self) -> None:
        """The process noise for the commands told so far (:func:`told_process_noise`)."""
        self._process.use_noise(told_process_noise(
            self._config, self._untold_noise, steering=self._commands.told,
            accel=self._accel_commands.told, steer_lag_s=self._steering.time_constant_s))

    def _follow_accel_command(self, t0_s: float, t1_s: float) -> None:
        """Move the acceleration's mean and variance by the drive's response to its
        commands over ``(t0_s, t1_s]`` ((A1)-(A2) of :mod:`estimation.accel_commands`)."""
        moved = self._accel_commands.moved(self._x, self._p, self._ax, t0_s, t1_s)
        if moved is not None:
            self._set_mean(moved[0])
            self._set_covariance(moved[1])

    # ------------------------------------------------------------------------------ update

    def _check(self, measurement: Measurement) -> CheckedMeasurement | tuple[str, int]:
        """What :meth:`update` fuses of ``measurement`` (its model, channels and values), or
        why it fuses nothing: ``(reason, dim)``. Changes nothing."""
        model = self._models.get(measurement.sensor)
        if model is None:
            return IGNORED, 0
        names = measurement.names
        selection = self._selection(model, names if type(names) is tuple else tuple(names))
        dim = len(selection.model_rows)
        if dim == 0:
            return IGNORED, 0
        values, covariance = measurement.values, measurement.covariance
        if not (type(values) is np.ndarray and values.dtype == np.float64 and values.ndim == 1):
            values = np.asarray(values, dtype=float).reshape(-1)
        if not (type(covariance) is np.ndarray and covariance.dtype == np.float64):
            covariance = np.asarray(covariance, dtype=float)
        size = len(measurement.names)
        if values.shape != (size,) or covariance.shape != (size, size):
            raise ValueError(
                f"{measurement.sensor} measurement: {size} names but values of shape "
                f"{values.shape} and covariance of shape {covariance.shape}"
            )
        # Every channel, in order: no selection needed.
        z = values if selection.every_column and len(selection.measurement_columns) == size \
            else values[selection.column_index]
        t_s = float(measurement.t_s)
        # Each of a measurement's few values tested as a float: numpy's isfinite and all
        # cost more for so few (the same test: NaN and both infinities are caught).
        if not (math.isfinite(t_s) and all(map(math.isfinite, z.tolist()))):
            return NON_FINITE, dim
        if is_stale(self._t_s, t_s):
            return STALE, dim
        return CheckedMeasurement(model, selection, z, t_s)

    def update(self, measurement: Measurement) -> UpdateResult:
        """Fuse one measurement at its own time (predicting to it first).

        Measurements of sensors the filter does not model are ignored (``accepted=False``,
        counted as ``ignored``). Non-finite, stale and gated measurements are rejected and
        counted; they never touch the state. Independent channels are gated one by one: a
        measurement with some channels gated is ``accepted`` with reason ``"partial"``, and
        its ``nis``/``dim`` are those of the fused channels.
        """
        sensor = measurement.sensor
        counts = self._counts.setdefault(sensor, SensorCounts())
        checked = self._check(measurement)
        if not isinstance(checked, CheckedMeasurement):
            reason, dim = checked
            counts.count_refusal(reason)
            return UpdateResult(False, math.nan, dim, reason)
        model, selection, z, t_s = checked.model, checked.selection, checked.z, checked.t_s
        dim = len(selection.model_rows)

        self.predict(t_s)
        r_matrix = np.diag(selection.model_variance)
        if self._awaiting_first_fix and sensor == "gnss" and dim == 2:
            self._take_first_fix(model, selection, z, r_matrix)
            counts.accepted += 1
            return UpdateResult(True, math.nan, dim, ACCEPTED)
        everything = tuple(range(dim))
        joint = self._innovation(model, selection, everything, z, r_matrix)
        if joint is None:
            counts.rejected_invalid += 1
            return UpdateResult(False, math.nan, dim, INVALID)
        surprise = (self._config.gate and self._config.inflate_on_surprise
                    and not self._config.gates(sensor) and joint.nis > self.gate_threshold(dim))
        nis = joint.nis  # reported: a surprise's NIS is the one before the room was made
        if surprise:
            # A sensor exempt from the gate far outside it: a manoeuvre the model did not
            # predict.
            _, jacobian = model.evaluate(self._x)
            shape = self._process.process_noise(self._x, self._config.max_step_s,
                                                self._commands.at(self._t_s))
            room = room_for_surprise(self._p, shape, jacobian[list(joint.rows), :],
                                     joint.trial.innovation, joint.nis, self.gate_threshold(dim))
            if room is not None:  # along the process noise of one sub-step at the mean
                self._set_covariance(room)
            counts.surprises += 1
            inflated = self._innovation(model, selection, everything, z, r_matrix)
            joint = inflated if inflated is not None else joint
        if not self._config.gates(sensor) or joint.nis <= self.gate_threshold(dim):
            # The common case: one joint update.
            self._forget_gate_failures(model, selection, everything)
            if not self._apply(joint):
                counts.rejected_invalid += 1
                return UpdateResult(False, nis, dim, INVALID, nis, dim)
            counts.accepted += 1
            return UpdateResult(True, nis, dim, ACCEPTED, nis, dim)
        result = self._gated_update(model, selection, z, r_matrix, t_s, counts)
        return dataclasses.replace(result, joint_nis=joint.nis, joint_dim=dim)

    def update_many(self, measurements: list[Measurement]) -> list[UpdateResult]:
        """Fuse measurements taken at the same instant; one result per measurement.

        When every one of them is fusable and passes its own gate against the prior, the
        filter fuses them in one update (:meth:`_joint_update`: for a linearised
        model the same posterior as one after another, Bar-Shalom, Li, Kirubarajan 2001,
        section 3.3.2, at a third of the cost for the IMU, wheel speeds and steering every
        10 ms); each measurement's NIS is its own block of the joint innovation against the
        prior, as :meth:`update` reports it. Otherwise (a gate, a rejection, a first fix,
        a filter without a joint update) they are fused one after another
        (:meth:`_one_by_one`).
        """
        checked = [self._check(m) for m in measurements]
        if (len(measurements) < 2 or self._awaiting_first_fix
                or not all(isinstance(c, CheckedMeasurement) for c in checked)
                or len({c.t_s for c in checked}) != 1):
            return self._one_by_one(measurements)
        self.predict(checked[0].t_s)
        joint = self._joint_update(checked)
        if joint is None:
            return self._one_by_one(measurements)
        for c, value in zip(checked, joint.nis, strict=True):
            # Above the gate, gated or not: one by one (a gate, or a surprise's room).
            if not math.isfinite(value) or (
                    self._config.gate and value > self.gate_threshold(len(c.selection.model_rows))):
                return self._one_by_one(measurements)
        if not self._commit(joint.mean, joint.covariance, symmetric=joint.symmetric,
                            checked=joint.positive_definite):
            return self._one_by_one(measurements)
        results = []
        counts = self._counts
        for c, value in zip(checked, joint.nis, strict=True):
            dim = len(c.selection.model_rows)
            if self._gate_failing_since_s:
                self._forget_gate_failures(c.model, c.selection, tuple(range(dim)))
            sensor = c.model.sensor
            if sensor not in counts:
                counts[sensor] = SensorCounts()
            counts[sensor].accepted += 1
            results.append(UpdateResult(True, value, dim, ACCEPTED, value, dim))
        return results

    def _one_by_one(self, measurements: list[Measurement]) -> list[UpdateResult]:
        """:meth:`update` of each, in :func:`estimation.update_order.linear_first`'s order;
        the results in the order given."""
        results = {i: self.update(measurements[i])
                   for i in linear_first(measurements, self._models)}
        return [results[i] for i in range(len(measurements))]

    def _joint_update(self, checked: list[CheckedMeasurement],
                      at: np.ndarray | None = None) -> JointPosterior | None:
        """Every measurement of ``checked`` in one update against the belief (the models
        linearised at ``at``, None: the mean) and each one's NIS (its block of the joint
        innovation); None without a joint update or a singular innovation covariance."""
        blocks = [(c.model, c.selection, c.z, np.diag(c.selection.model_variance))
                  for c in checked]
        try:
            trial = self._joint_trial_update(blocks, at)
        except np.linalg.LinAlgError:
            trial = None
        if trial is None:
            return None
        return JointPosterior(trial.mean, trial.covariance, block_nis(
            trial, [len(c.selection.model_rows) for c in checked]))

    def _joint_trial_update(
        self, blocks: list[tuple[MeasurementModel, Selection, np.ndarray, np.ndarray]],
        at: np.ndarray | None = None) -> TrialUpdate | None:
        """One update with several measurements' channels at once (model, selection,
        values, noise per measurement, stacked; the models linearised at ``at``, None: the
        mean), the belief unchanged; None without one (:meth:`update_many`: one by one)."""
        del blocks, at
        return None

    def _gated_update(
        self,
        model: MeasurementModel,
        selection: Selection,
        z: np.ndarray,
        r_matrix: np.ndarray,
        t_s: float,
        counts: SensorCounts,
    ) -> UpdateResult:
        """A measurement whose joint NIS failed the gate: its channels gated one by one."""
        dim = len(selection.model_rows)
        everything = tuple(range(dim))

        # Above the gate. Independent channels (diagonal R) are then gated one by one and
        # fused sequentially, so a spinning wheel or a lateral-acceleration transient costs
        # only its own channel (for a linear model sequential fusion equals the joint
        # update: Bar-Shalom, Li, Kirubarajan 2001, section 3.3.2). Correlated channels
        # stay one group.
        if np.any(r_matrix - np.diag(np.diag(r_matrix))):
            groups = [everything]
        else:
            groups = [(i,) for i in everything]
        fused_nis, fused_dim, tested_nis = 0.0, 0, 0.0
        gated = released = invalid = 0
        for group in groups:
            outcome, nis = self._gate_and_fuse(model, selection, group, z, r_matrix, t_s)
            if math.isfinite(nis):
                tested_nis += nis
            if outcome in (ACCEPTED, GATE_RELEASED):
                fused_nis += nis
                fused_dim += len(group)
                released += outcome == GATE_RELEASED
            elif outcome == GATE:
                gated += len(group)
            else:
                invalid += 1
        counts.channels_gated += gated
        counts.gate_released += released
        if fused_dim == 0:
            if gated:
                counts.rejected_gate += 1
                return UpdateResult(False, tested_nis, dim, GATE)
            counts.rejected_invalid += 1
            return UpdateResult(False, math.nan, dim, INVALID)
        counts.accepted += 1
        if gated or invalid:
            return UpdateResult(True, fused_nis, fused_dim, PARTIAL)
        return UpdateResult(True, fused_nis, fused_dim, GATE_RELEASED if released else ACCEPTED)

    def _innovation(
        self,
        model: MeasurementModel,
        selection: Selection,
        group: tuple[int, ...],
        z: np.ndarray,
        r_matrix: np.ndarray,
    ) -> Innovation | None:
        """The channels ``group`` (indices into ``z``) against the current belief: the
        filter's trial update and its NIS. ``None`` if the innovation covariance is not
        positive definite."""
        if len(group) == len(selection.model_rows):  # every channel (the common case)
            rows, angle_rows = selection.model_rows, selection.angle_rows
            z_group, r_group = z, r_matrix
        else:
            index = list(group)
            rows = tuple(selection.model_rows[i] for i in index)
            angle_rows = tuple(j for j, i in enumerate(group) if i in selection.angle_rows)
            z_group, r_group = z[index], r_matrix[np.ix_(index, index)]
        residual = residual_function(angle_rows)
        try:
            trial = self._trial_update(model, rows, z_group, r_group, residual, angle_rows)
        except np.linalg.LinAlgError:
            return None
        nis = normalised_innovation_squared(trial)
        return Innovation(rows, nis, trial) if math.isfinite(nis) else None

    def _apply(self, innovation: Innovation) -> bool:
        """Commit a trial update (:meth:`_commit`)."""
        return self._commit(innovation.trial.mean, innovation.trial.covariance)

    def _commit(self, mean: np.ndarray, covariance: np.ndarray,
                symmetric: bool = False, checked: bool = False) -> bool:
        """Make ``mean`` and ``covariance`` (symmetrised, unless the caller's is
        ``symmetric`` to the bit, as the joint update's is) the belief; refuse (False, the
        belief unchanged) if they are non-finite or the covariance not positive definite
        (``checked``: the caller knows they are not, as the compiled joint update does)."""
        mean = np.asarray(mean, dtype=float).reshape(-1)
        covariance = np.asarray(covariance, dtype=float)
        if not symmetric:
            covariance = 0.5 * (covariance + covariance.T)
        if not checked:
            if not (np.isfinite(mean).all() and np.isfinite(covariance).all()):
                return False
            try:
                np.linalg.cholesky(covariance)
            except np.linalg.LinAlgError:
                return False
        self._set_covariance(covariance)  # symmetric already: _normalise's mean only
        self._set_wrapped_mean(mean)
        return True

    def _gate_and_fuse(
        self,
        model: MeasurementModel,
        selection: Selection,
        group: tuple[int, ...],
        z: np.ndarray,
        r_matrix: np.ndarray,
        t_s: float,
    ) -> tuple[str, float]:
        """Gate and fuse the channels ``group`` on their own: outcome and NIS."""
        innovation = self._innovation(model, selection, group, z, r_matrix)
        if innovation is None:
            return INVALID, math.nan
        key = selection.gate_key(model, group)
        if innovation.nis <= self.gate_threshold(len(group)):
            self._gate_failing_since_s.pop(key, None)
            if not self._apply(innovation):
                return INVALID, innovation.nis
            return ACCEPTED, innovation.nis
        since_s = self._gate_failing_since_s.setdefault(key, t_s)
        if t_s - since_s < self._config.gate_release_s:
            return GATE, innovation.nis
        released_nis = innovation.nis  # reported: the disagreement that was believed
        _, jacobian = model.evaluate(self._x)
        self._set_covariance(room_for_jump(  # estimation.covariance_room
            self._p, jacobian[list(innovation.rows), :], innovation.trial.innovation))
        inflated = self._innovation(model, selection, group, z, r_matrix)
        if inflated is None or not self._apply(inflated):
            return INVALID, released_nis
        return GATE_RELEASED, released_nis

    def _forget_gate_failures(
        self, model: MeasurementModel, selection: Selection, group: tuple[int, ...]
    ) -> None:
        if self._gate_failing_since_s:
            self._gate_failing_since_s.pop(selection.gate_key(model, group), None)
            for i in group:
                self._gate_failing_since_s.pop(selection.gate_key(model, (i,)), None)

    # ----------------------------------------------------------------------------- helpers

    def _take_first_fix(
        self, model: MeasurementModel, selection: Selection, z: np.ndarray, r_matrix: np.ndarray
    ) -> None:
        """:func:`estimation.covariance_room.first_fix`."""
        rows = [state_index(model.channels[row]) for row in selection.model_rows]
        mean, covariance = first_fix(self._x, self._p, rows, z, r_matrix)
        self._set_mean(mean)
        self._set_covariance(covariance)
        self._awaiting_first_fix = False

    def _selection(self, model: MeasurementModel, names: tuple[str, ...]) -> Selection:
        key = (model.sensor, names)
        if key not in self._selections:
            self._selections[key] = Selection.of(
                model, names, self._noise_variances.get(model.sensor, {}))
        return self._selections[key]

    def _normalise(self) -> None:
        """Wrap the angle states and symmetrise the covariance."""
        self._set_wrapped_mean(self._x)
        p = self._p
        self._set_covariance(0.5 * (p + p.T))

    def _set_wrapped_mean(self, mean: np.ndarray) -> None:
        x = np.array(mean, dtype=float).reshape(-1)
        for index in self._angle_indices:
            angle = x[index]
            if not -math.pi < angle <= math.pi:  # inside, wrap_angle returns it untouched
                x[index] = wrap_angle(angle)
        self._set_mean(x)

