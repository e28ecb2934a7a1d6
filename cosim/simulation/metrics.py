"""Run metrics, from what the loop saw (every key, its unit and meaning:
:mod:`cosim.simulation.metric_keys`, ``docs/metrics.md``).

Tracking errors use the true centre of gravity projected onto the reference path (not
y - y_ref); heading error is the true yaw minus the path's yaw at that projection, wrapped
to (-pi, pi]. NEES is over (x, y, yaw, speed), 4 degrees of freedom, so its mean should sit
near 4 for a consistent filter (but the time average of one run is no test of that: its
samples are correlated; :mod:`estimation.consistency` tests an ensemble). ``nis_mean`` is the
mean of NIS divided by the measurement's dimension over every update the filter tested
against its prior, gated ones included (1 for a consistent filter, whatever the sensor);
``nis_<sensor>`` (``nis_gnss``, ``nis_imu``, ``nis_wheel_speed``, ``nis_steering``, ...) is
the same for one sensor: its summed NIS over its summed channels (``nis_dof_<sensor>``),
the NIS per degree of freedom (Bar-Shalom, Li, Kirubarajan, "Estimation with Applications
to Tracking and Navigation", Wiley 2001, section 5.4.2). ``nis_settled_<sensor>`` is the same
over the updates at or after the settling time (:data:`estimation.consistency.SETTLE_S`, the
time the ANEES is judged from), so that the prior's convergence at start-up does not hide a
filter that is wrong once settled; ``gated_first_s_<sensor>`` counts the sensor's updates
before that time that the gate refused in whole or in part (a start-up that is consistent
gates none).
The speed error is against the reference's speed profile at the projection and the time.

Comfort, from the truth at the log rate: ``lat_accel_max_mps2`` is the largest lateral
acceleration of the centre of gravity (vehicle frame); ``jerk_rms_mps3`` the RMS of the
magnitude of the planar jerk (finite differences of the vehicle-frame longitudinal and
lateral accelerations between log samples) and ``lat_jerk_rms_mps3`` that of its lateral
part, the two figures ride-comfort studies rank controllers by (e.g. ISO 2631-1's weighting
aside, peak lateral acceleration and RMS jerk are the usual path-tracking comfort figures).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

from cosim.core.records import Command, Estimate, Plan, VehicleState
from cosim.simulation.manoeuvre_metrics import manoeuvre_metrics
from cosim.simulation.metric_keys import METRIC_KEYS, WALL_CLOCK_KEYS
from cosim.simulation.running_stats import RunningStats, SampleBlock, Samples
from estimation.consistency import SETTLE_S
from estimation.update_result import GATE, PARTIAL, UpdateResult
from tracker.manoeuvre import ManoeuvreConfig
from tracker.paths.reference_path import ReferencePath, wrap_angle

NEES_STATES = ("x_m", "y_m", "yaw_rad", "vx_mps")
"""The states NEES is computed over (4 degrees of freedom)."""

TRUTH_STATISTICS = ("cte_m", "heading_err_rad", "speed_err_mps")
"""The statistics of each truth sample against the reference (``add_truth``)."""

ESTIMATE_STATISTICS = ("pos_err_m", "yaw_err_rad", "speed_est_err_mps", "nees")
"""The statistics of each estimate against the truth (``add_estimate``)."""

__all__ = ["METRIC_KEYS", "NEES_STATES", "WALL_CLOCK_KEYS", "MetricsAccumulator",
           "rejection_counts"]


REJECTION_CAUSES = ("rejected_gate", "rejected_nonfinite", "rejected_stale",
                    "rejected_invalid")


def rejection_counts(counts: dict[str, dict[str, int]]) -> dict[str, int]:
    """``rejected_measurements`` (whole measurements refused, all causes), the same per
    cause, and ``channels_gated`` (single channels the gate refused, also inside partly
    fused measurements), and ``estimator_surprises`` (ungated measurements far outside the
    gate, fused after the filter made room for a manoeuvre), from an estimator's
    per-sensor counters."""
    totals = {cause: sum(c.get(cause, 0) for c in counts.values())
              for cause in REJECTION_CAUSES}
    return {
        "rejected_measurements": sum(totals.values()),
        **totals,
        "channels_gated": sum(c.get("channels_gated", 0) for c in counts.values()),
        "estimator_surprises": sum(c.get("surprises", 0) for c in counts.values()),
    }


def percentiles(values: np.ndarray, percents: tuple[float, ...]) -> tuple[float, ...]:
    """``np.percentile(values, percents)`` of 1-D ``values`` (one at least), to the
    bit: numpy's default (linear) method, the sorted values' virtual index ``(n - 1) q /
    100`` between its two neighbours ``a <= b``, ``a + (b - a) g`` for a fraction ``g <
    0.5``, else ``b - (b - a)(1 - g)`` (Hyndman and Fan, "Sample quantiles in statistical
    packages", The American Statistician 1996, definition 7). Written out because
    ``np.percentile`` imports ``numpy.ma`` on its way (through ``np.unique``), some 10 ms
    of every process that reports a run's solve times."""
    ordered = np.sort(np.asarray(values, dtype=float).reshape(-1))
    if np.isnan(ordered[-1]):  # sorted last: numpy's percentiles are NaN then
        return (math.nan,) * len(percents)
    last = ordered.size - 1
    found = []
    for percent in percents:
        virtual = last * (percent / 100)
        below = min(math.floor(virtual), last)
        a, b = float(ordered[below]), float(ordered[min(below + 1, last)])
        fraction = virtual - below
        found.append(b - (b - a) * (1 - fraction) if fraction >= 0.5 else a + (b - a) * fraction)
    return tuple(found)


def _millisecond_percentiles(prefix: str, times_s: np.ndarray) -> dict[str, float]:
    """``<prefix>_p50``, ``_p99`` and ``_max`` of ``times_s`` in milliseconds (NaN if none)."""
    times_ms = np.asarray(times_s, dtype=float) * 1e3
    times_ms = times_ms[np.isfinite(times_ms)]
    if not times_ms.size:
        return {f"{prefix}_p50": float("nan"), f"{prefix}_p99": float("nan"),
                f"{prefix}_max": float("nan")}
    p50, p99 = percentiles(times_ms, (50.0, 99.0))
    return {f"{prefix}_p50": float(p50), f"{prefix}_p99": float(p99),
            f"{prefix}_max": float(times_ms.max())}


@dataclass
class MetricsAccumulator:
    """Collects what the metrics need while a run goes, in constant memory (but for the
    solve times and an open-loop manoeuvre's signals); :meth:`result` computes them.

    Each log instant's tracking and estimation samples go into preallocated blocks
    (:class:`SampleBlock`), reduced into the statistics with numpy each time a block fills
    (NEES as one batched solve). Reading a figure merges the pending rows into copies, so
    the blocks' boundaries, and so every sum's rounding, do not depend on when or whether
    figures were read (a logged run's live metrics): the same samples give the same figures
    bit for bit. The last tracking errors, which the monitors read at every instant, are
    kept as plain numbers (:attr:`last_cte_m` ...).
    """

    reference: ReferencePath
    manoeuvre: ManoeuvreConfig | None = None
    """Set for open-loop runs: adds the manoeuvre's steady-state (and step) metrics."""
    t_s: Samples = field(default_factory=Samples)
    true_steer_rad: Samples = field(default_factory=Samples)
    yaw_rate_radps: Samples = field(default_factory=Samples)
    ay_mps2: Samples = field(default_factory=Samples)
    speed_mps: Samples = field(default_factory=Samples)
    _truth_stats: tuple[RunningStats, ...] = field(
        default_factory=lambda: tuple(RunningStats() for _ in TRUTH_STATISTICS), init=False)
    """The :data:`TRUTH_STATISTICS` over the reduced blocks."""
    last_cte_m: float = float("nan")
    """Cross-track error of the last truth sample [m] (left of the path positive)."""
    last_heading_err_rad: float = float("nan")
    """Heading error of the last truth sample [rad], wrapped to (-pi, pi]."""
    last_speed_err_mps: float = float("nan")
    """Speed error of the last truth sample against the reference [m/s]."""
    last_ref_speed_mps: float = float("nan")
    """The reference speed at the last truth sample's projection and time [m/s]."""
    lat_accel_mps2: RunningStats = field(default_factory=RunningStats)
    jerk_mps3: RunningStats = field(default_factory=RunningStats)
    lat_jerk_mps3: RunningStats = field(default_factory=RunningStats)
    last_accel: tuple[float, float, float] | None = None
    """``(t_s, ax_mps2, ay_mps2)`` of the last truth sample, for the jerk's differences."""
    steer_rad: RunningStats = field(default_factory=RunningStats)
    accel_mps2: RunningStats = field(default_factory=RunningStats)
    solve_time_s: Samples = field(default_factory=Samples)
    step_time_s: Samples = field(default_factory=Samples)
    """Wall time of each whole ``tracker.step``: latency prediction, projection, linearisation,
    QP or NLP set-up and solve (measured by the runner around the call, for every tracker)."""
    solver_failures: int = 0
    speed_reduced_steps: int = 0
    """Control steps whose plan slowed below the reference speed (``Plan.speed_reduced``)."""
    _estimate_stats: tuple[RunningStats, ...] = field(
        default_factory=lambda: tuple(RunningStats() for _ in ESTIMATE_STATISTICS),
        init=False)
    """The :data:`ESTIMATE_STATISTICS` over the reduced blocks."""
    nis_per_dof: RunningStats = field(default_factory=RunningStats)
    nis_sum: dict[str, float] = field(default_factory=dict)
    """Per sensor, the summed NIS of every tested update (gated included)."""
    nis_dof: dict[str, int] = field(default_factory=dict)
    """Per sensor, the summed dimension of those updates."""
    settle_s: float = SETTLE_S
    """Updates at or after this time [s] make ``nis_settled_<sensor>``; gated updates
    before it are counted in ``gated_first_s_<sensor>``."""
    nis_settled_sum: dict[str, float] = field(default_factory=dict)
    """Per sensor, the summed NIS of the tested updates at or after :attr:`settle_s`."""
    nis_settled_dof: dict[str, int] = field(default_factory=dict)
    """Per sensor, the summed dimension of those updates."""
    gated_first_s: dict[str, int] = field(default_factory=dict)
    """Per sensor, the updates before :attr:`settle_s` the gate refused in whole or in part."""
    tested_first_s: dict[str, int] = field(default_factory=dict)
    """Per sensor, the updates before :attr:`settle_s` with a NIS (what a gate tested): a
    consistent filter's gate refuses a fraction ``1 - estimator.gate_probability`` of them
    (:func:`estimation.consistency.false_alarms`)."""
    updates_gated: dict[str, int] = field(default_factory=dict)
    """Per sensor, the updates of the whole run the gate refused in whole or in part."""
    updates_tested: dict[str, int] = field(default_factory=dict)
    """Per sensor, the updates of the whole run with a NIS, gated or not."""
    estimator_counts: dict[str, dict[str, int]] = field(default_factory=dict)
    """Per sensor, the estimator's own counters (set at the end of the run)."""
    last_t_s: float = 0.0
    _estimate_names: tuple[str, ...] = field(default=(), init=False, repr=False)
    """The estimates' state names (an estimator keeps its names)."""
    _nees_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int),
                                    init=False, repr=False)
    """Where the :data:`NEES_STATES` are among :attr:`_estimate_names`."""
    _estimate_block: SampleBlock | None = field(default=None, init=False, repr=False)
    """Per log instant: the estimate of the NEES states, the truth of them, and the
    estimate's whole covariance (sized at the first estimate)."""
    _truth_block: SampleBlock = field(init=False, repr=False)
    """Per log instant: cross-track, heading and speed errors."""
    last_path_s_m: float | None = None
    """Arc length of the last projection of the truth onto the reference path."""

    def __post_init__(self) -> None:
        self._truth_block = SampleBlock(
            len(TRUTH_STATISTICS), lambda rows: _reduce_truth(rows, self._truth_stats))

    def add_truth(self, truth: VehicleState) -> None:
        # Searched near the previous projection: the car moves < 1 m between log samples.
        projection = self.reference.project(truth.x_m, truth.y_m, self.last_path_s_m)
        self.last_path_s_m = projection.s_m
        self.last_cte_m = cte_m = projection.lateral_error_m
        self.last_heading_err_rad = heading_err_rad = float(
            wrap_angle(truth.yaw_rad - projection.path_yaw_rad))
        ref_speed = self.reference.speed_ref_at(projection.s_m, truth.t_s)
        self.last_ref_speed_mps = ref_speed
        self.last_speed_err_mps = speed_err_mps = truth.speed_mps - ref_speed
        self._truth_block.add((cte_m, heading_err_rad, speed_err_mps))
        self._add_comfort(truth)
        self.last_t_s = truth.t_s
        if self.manoeuvre is not None:
            self.t_s.add(truth.t_s)
            self.true_steer_rad.add(truth.steer_rad)
            self.yaw_rate_radps.add(truth.yaw_rate_radps)
            self.ay_mps2.add(truth.ay_mps2)
            self.speed_mps.add(truth.speed_mps)

    def add_estimate(self, estimate: Estimate, truth: VehicleState) -> None:
        """The estimate's errors against ``truth`` over :data:`NEES_STATES` (position,
        yaw wrapped to (-pi, pi], speed) and their NEES, ``e' P^-1 e`` with ``P`` the
        estimate's covariance of those states (left out where ``P`` is not finite and
        positive definite)."""
        if estimate.names != self._estimate_names:
            if self._estimate_block is not None:  # (an estimator keeps its names)
                self._estimate_block.flush()
            self._estimate_names = estimate.names
            self._nees_index = np.array([estimate.names.index(n) for n in NEES_STATES])
            self._estimate_block = SampleBlock(
                2 * len(NEES_STATES) + estimate.covariance.size,
                lambda rows: _reduce_estimates(rows, self._nees_index, self._estimate_stats))
        assert self._estimate_block is not None
        row = self._estimate_block.next_row()
        row[0:4] = estimate.mean[self._nees_index]
        row[4:8] = (truth.x_m, truth.y_m, truth.yaw_rad, truth.vx_mps)
        row[8:] = estimate.covariance.reshape(-1)

    def statistics(self) -> dict[str, RunningStats]:
        """Every per-sample statistic over the samples so far, by name
        (:data:`TRUTH_STATISTICS`, :data:`ESTIMATE_STATISTICS`): copies with the pending
        rows merged in; the accumulator itself is left as it was."""
        truth = tuple(map(copy.copy, self._truth_stats))
        _reduce_truth(self._truth_block.pending(), truth)
        estimates = tuple(map(copy.copy, self._estimate_stats))
        if self._estimate_block is not None:
            _reduce_estimates(self._estimate_block.pending(), self._nees_index, estimates)
        return dict(zip(TRUTH_STATISTICS + ESTIMATE_STATISTICS, truth + estimates,
                        strict=True))

    def add_update(self, sensor: str, update: UpdateResult, t_s: float) -> None:
        """One measurement's outcome at its time ``t_s``: its NIS over all its channels
        against the prior, whether the gate then fused it or not."""
        nis, dim = update.joint_nis, update.joint_dim
        if dim > 0 and math.isfinite(nis):
            self.nis_per_dof.add(nis / dim)
            self.nis_sum[sensor] = self.nis_sum.get(sensor, 0.0) + nis
            self.nis_dof[sensor] = self.nis_dof.get(sensor, 0) + dim
            gated = update.reason in (GATE, PARTIAL)
            self.updates_gated[sensor] = self.updates_gated.get(sensor, 0) + gated
            self.updates_tested[sensor] = self.updates_tested.get(sensor, 0) + 1
            if t_s >= self.settle_s:
                self.nis_settled_sum[sensor] = self.nis_settled_sum.get(sensor, 0.0) + nis
                self.nis_settled_dof[sensor] = self.nis_settled_dof.get(sensor, 0) + dim
            else:
                self.gated_first_s[sensor] = self.gated_first_s.get(sensor, 0) + gated
                self.tested_first_s[sensor] = self.tested_first_s.get(sensor, 0) + 1

    def add_plan(self, plan: Plan, step_time_s: float = float("nan")) -> None:
        self.solve_time_s.add(plan.solve_time_s)
        self.step_time_s.add(step_time_s)
        if plan.fallback:
            self.solver_failures += 1
        if plan.speed_reduced:
            self.speed_reduced_steps += 1

    def add_command(self, command: Command) -> None:
        self.steer_rad.add(command.steer_rad)
        self.accel_mps2.add(command.accel_mps2)

    def _tracking(self, stats: dict[str, RunningStats]) -> dict[str, float]:
        """The tracking metrics of ``stats`` (:meth:`statistics`)."""
        return {
            "cte_max_m": stats["cte_m"].max_abs,
            "cte_rms_m": stats["cte_m"].rms,
            "heading_err_max_rad": stats["heading_err_rad"].max_abs,
            "heading_err_rms_rad": stats["heading_err_rad"].rms,
            "speed_err_rms_mps": stats["speed_err_mps"].rms,
            "speed_err_max_mps": stats["speed_err_mps"].max_abs,
            "steer_max_rad": self.steer_rad.max_abs,
        }

    def live(self, t_s: float) -> dict[str, float | int]:
        """The metrics that can be computed so far, for ``/metrics/live`` at sim time
        ``t_s`` (same keys and meaning as :meth:`result`'s, over the run up to ``t_s``)."""
        solve_ms = self.solve_time_s.as_array() * 1e3
        stats = self.statistics()
        return {
            "t_s": t_s,
            "cte_m": self.last_cte_m,
            **self._tracking(stats),
            "solve_ms_p50": percentiles(solve_ms, (50.0,))[0] if solve_ms.size else math.nan,
            "solve_ms_max": float(solve_ms.max()) if solve_ms.size else float("nan"),
            "solver_failures": self.solver_failures,
            "est_pos_rmse_m": stats["pos_err_m"].rms,
            "est_yaw_rmse_rad": stats["yaw_err_rad"].rms,
            "nees_mean": stats["nees"].mean,
            "nis_mean": self.nis_per_dof.mean,
        }

    def result(self, wall_time_s: float, completed: bool) -> dict[str, float | int | bool]:
        """Every metric; NaN where a quantity has no samples (e.g. NEES of ``truth``)."""
        solve_ms = self.solve_time_s.as_array() * 1e3

        def percentile(q: float) -> float:
            return percentiles(solve_ms, (q,))[0] if solve_ms.size else math.nan

        sim_duration_s = self.last_t_s
        stats = self.statistics()
        extra: dict[str, float] = {}
        if self.manoeuvre is not None:
            extra = manoeuvre_metrics(
                self.t_s.as_array(), self.true_steer_rad.as_array(),
                self.yaw_rate_radps.as_array(), self.ay_mps2.as_array(),
                self.speed_mps.as_array(), self.manoeuvre)
        return {
            **self._tracking(stats),
            "accel_max_mps2": self.accel_mps2.maximum,
            "accel_min_mps2": self.accel_mps2.minimum,
            "solve_ms_p50": percentile(50),
            "solve_ms_p99": percentile(99),
            "solve_ms_max": float(solve_ms.max()) if solve_ms.size else float("nan"),
            **_millisecond_percentiles("step_ms", self.step_time_s.as_array()),
            "solver_failures": self.solver_failures,
            "speed_reduced_steps": self.speed_reduced_steps,
            "est_pos_rmse_m": stats["pos_err_m"].rms,
            "est_yaw_rmse_rad": stats["yaw_err_rad"].rms,
            "est_speed_rmse_mps": stats["speed_est_err_mps"].rms,
            "nees_mean": stats["nees"].mean,
            "nis_mean": self.nis_per_dof.mean,
            **{f"nis_{sensor}": self.nis_sum[sensor] / self.nis_dof[sensor]
               for sensor in sorted(self.nis_sum)},
            **{f"nis_dof_{sensor}": self.nis_dof[sensor] for sensor in sorted(self.nis_dof)},
            **{f"nis_settled_{sensor}": self.nis_settled_sum[sensor]
               / self.nis_settled_dof[sensor] for sensor in sorted(self.nis_settled_sum)},
            **{f"nis_settled_dof_{sensor}": self.nis_settled_dof[sensor]
               for sensor in sorted(self.nis_settled_dof)},
            **{f"gated_first_s_{sensor}": self.gated_first_s[sensor]
               for sensor in sorted(self.gated_first_s)},
            **{f"tested_first_s_{sensor}": self.tested_first_s[sensor]
               for sensor in sorted(self.tested_first_s)},
            **{f"updates_gated_{sensor}": self.updates_gated[sensor]
               for sensor in sorted(self.updates_gated)},
            **{f"updates_tested_{sensor}": self.updates_tested[sensor]
               for sensor in sorted(self.updates_tested)},
            **rejection_counts(self.estimator_counts),
            "sim_duration_s": sim_duration_s,
            "wall_time_s": wall_time_s,
            "realtime_factor": sim_duration_s / wall_time_s if wall_time_s > 0 else float("nan"),
            "completed": completed,
            **self.comfort(),
            **extra,
        }

    def _add_comfort(self, truth: VehicleState) -> None:
        # Before the first physics step the plant has no accelerations yet (they read 0):
        # that sample would turn the start into a jerk of a few hundred m/s^3.
        if truth.t_s <= 0.0:
            return
        self.lat_accel_mps2.add(truth.ay_mps2)
        if self.last_accel is not None:
            last_t_s, last_ax, last_ay = self.last_accel
            dt = truth.t_s - last_t_s
            if dt > 0.0:
                jerk_x = (truth.ax_mps2 - last_ax) / dt
                jerk_y = (truth.ay_mps2 - last_ay) / dt
                self.jerk_mps3.add(float(np.hypot(jerk_x, jerk_y)))
                self.lat_jerk_mps3.add(jerk_y)
        self.last_accel = (truth.t_s, truth.ax_mps2, truth.ay_mps2)

    def comfort(self) -> dict[str, float]:
        """``lat_accel_max_mps2``, ``jerk_rms_mps3``, ``lat_jerk_rms_mps3`` (module docstring)."""
        return {"lat_accel_max_mps2": self.lat_accel_mps2.max_abs,
                "jerk_rms_mps3": self.jerk_mps3.rms,
                "lat_jerk_rms_mps3": self.lat_jerk_mps3.rms}


def _reduce_truth(rows: np.ndarray, stats: tuple[RunningStats, ...]) -> None:
    """Merge rows of :data:`TRUTH_STATISTICS` into ``stats`` (in that order)."""
    for column, statistic in enumerate(stats):
        statistic.merge(rows[:, column])


def _reduce_estimates(rows: np.ndarray, nees_index: np.ndarray,
                      stats: tuple[RunningStats, ...]) -> None:
    """Merge rows of (estimate of the NEES states, their truth, the estimate's whole
    covariance) into ``stats`` (:data:`ESTIMATE_STATISTICS`); ``nees_index`` locates the
    NEES states in the covariance."""
    pos_err, yaw_err, speed_err, nees = stats
    error = rows[:, 0:4] - rows[:, 4:8]
    error[:, 2] = wrap_angle(error[:, 2])
    pos_err.merge(np.hypot(error[:, 0], error[:, 1]))
    yaw_err.merge(error[:, 2])
    speed_err.merge(error[:, 3])
    size = math.isqrt(rows.shape[1] - 8)
    covariance = rows[:, 8:].reshape(-1, size, size)[:, nees_index[:, None], nees_index]
    usable = np.all(np.isfinite(covariance), axis=(1, 2))
    usable[usable] = np.linalg.det(covariance[usable]) > 0.0
    weighted = np.linalg.solve(covariance[usable], error[usable][:, :, None])[:, :, 0]
    nees.merge(np.einsum("ij,ij->i", error[usable], weighted))
