"""Run metrics (the keys of docs/architecture.md's metrics table), from the logged records.

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
to Tracking and Navigation", Wiley 2001, section 5.4.2).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cosim.records import Command, Estimate, Plan, VehicleState
from cosim.simulation.maneuver_metrics import maneuver_metrics
from estimation.update_result import UpdateResult
from tracker.maneuver import ManeuverConfig
from tracker.reference_path import ReferencePath, wrap_angle

NEES_STATES = ("x_m", "y_m", "yaw_rad", "vx_mps")
"""The states NEES is computed over (4 degrees of freedom)."""

METRIC_KEYS = (
    "cte_max_m", "cte_rms_m", "heading_err_max_rad", "heading_err_rms_rad",
    "speed_err_rms_mps", "steer_max_rad", "accel_max_mps2", "accel_min_mps2",
    "solve_ms_p50", "solve_ms_p99", "solve_ms_max", "solver_failures",
    "est_pos_rmse_m", "est_yaw_rmse_rad", "est_speed_rmse_mps", "nees_mean", "nis_mean",
    "sim_duration_s", "wall_time_s", "realtime_factor", "completed",
)
"""Keys every run's metrics hold (a contract: outside tests read them)."""


REJECTION_CAUSES = ("rejected_gate", "rejected_nonfinite", "rejected_stale",
                    "rejected_invalid")


def rejection_counts(counts: dict[str, dict[str, int]]) -> dict[str, int]:
    """``rejected_measurements`` (whole measurements refused, all causes), the same per
    cause, and ``channels_gated`` (single channels the gate refused, also inside partly
    fused measurements), from an estimator's per-sensor counters."""
    totals = {cause: sum(c.get(cause, 0) for c in counts.values())
              for cause in REJECTION_CAUSES}
    return {
        "rejected_measurements": sum(totals.values()),
        **totals,
        "channels_gated": sum(c.get("channels_gated", 0) for c in counts.values()),
    }


def _rms(values: list[float] | np.ndarray) -> float:
    array = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(array**2))) if array.size else float("nan")


def _max_abs(values: list[float] | np.ndarray) -> float:
    array = np.asarray(values, dtype=float)
    return float(np.max(np.abs(array))) if array.size else float("nan")


@dataclass
class MetricsAccumulator:
    """Collects what the metrics need while a run goes; :meth:`result` computes them."""

    reference: ReferencePath
    maneuver: ManeuverConfig | None = None
    """Set for open-loop runs: adds the manoeuvre's steady-state (and step) metrics."""
    t_s: list[float] = field(default_factory=list)
    true_steer_rad: list[float] = field(default_factory=list)
    yaw_rate_radps: list[float] = field(default_factory=list)
    ay_mps2: list[float] = field(default_factory=list)
    speed_mps: list[float] = field(default_factory=list)
    cte_m: list[float] = field(default_factory=list)
    heading_err_rad: list[float] = field(default_factory=list)
    speed_err_mps: list[float] = field(default_factory=list)
    steer_rad: list[float] = field(default_factory=list)
    accel_mps2: list[float] = field(default_factory=list)
    solve_time_s: list[float] = field(default_factory=list)
    solver_failures: int = 0
    pos_err_m: list[float] = field(default_factory=list)
    yaw_err_rad: list[float] = field(default_factory=list)
    speed_est_err_mps: list[float] = field(default_factory=list)
    nees: list[float] = field(default_factory=list)
    nis_per_dof: list[float] = field(default_factory=list)
    nis_sum: dict[str, float] = field(default_factory=dict)
    """Per sensor, the summed NIS of every tested update (gated included)."""
    nis_dof: dict[str, int] = field(default_factory=dict)
    """Per sensor, the summed dimension of those updates."""
    estimator_counts: dict[str, dict[str, int]] = field(default_factory=dict)
    """Per sensor, the estimator's own counters (set at the end of the run)."""
    last_t_s: float = 0.0

    def add_truth(self, truth: VehicleState) -> None:
        projection = self.reference.project(truth.x_m, truth.y_m)
        self.cte_m.append(projection.lateral_error_m)
        self.heading_err_rad.append(float(wrap_angle(truth.yaw_rad - projection.path_yaw_rad)))
        self.speed_err_mps.append(truth.speed_mps - self.reference.speed_mps)
        self.last_t_s = truth.t_s
        if self.maneuver is not None:
            self.t_s.append(truth.t_s)
            self.true_steer_rad.append(truth.steer_rad)
            self.yaw_rate_radps.append(truth.yaw_rate_radps)
            self.ay_mps2.append(truth.ay_mps2)
            self.speed_mps.append(truth.speed_mps)

    def add_estimate(self, estimate: Estimate, truth: VehicleState) -> None:
        error = np.array([
            estimate["x_m"] - truth.x_m,
            estimate["y_m"] - truth.y_m,
            float(wrap_angle(estimate["yaw_rad"] - truth.yaw_rad)),
            estimate["vx_mps"] - truth.vx_mps,
        ])
        self.pos_err_m.append(float(np.hypot(error[0], error[1])))
        self.yaw_err_rad.append(float(error[2]))
        self.speed_est_err_mps.append(float(error[3]))
        covariance = estimate.sub_covariance(NEES_STATES)
        if np.all(np.isfinite(covariance)) and np.linalg.det(covariance) > 0.0:
            self.nees.append(float(error @ np.linalg.solve(covariance, error)))

    def add_update(self, sensor: str, update: UpdateResult) -> None:
        """One measurement's outcome: its NIS over all its channels against the prior,
        whether the gate then fused it or not."""
        nis, dim = update.joint_nis, update.joint_dim
        if dim > 0 and np.isfinite(nis):
            self.nis_per_dof.append(nis / dim)
            self.nis_sum[sensor] = self.nis_sum.get(sensor, 0.0) + nis
            self.nis_dof[sensor] = self.nis_dof.get(sensor, 0) + dim

    def add_plan(self, plan: Plan) -> None:
        self.solve_time_s.append(plan.solve_time_s)
        if plan.fallback:
            self.solver_failures += 1

    def add_command(self, command: Command) -> None:
        self.steer_rad.append(command.steer_rad)
        self.accel_mps2.append(command.accel_mps2)

    def result(self, wall_time_s: float, completed: bool) -> dict[str, float | int | bool]:
        """Every metric; NaN where a quantity has no samples (e.g. NEES of ``truth``)."""
        solve_ms = np.asarray(self.solve_time_s) * 1e3
        accel = np.asarray(self.accel_mps2)

        def percentile(q: float) -> float:
            return float(np.percentile(solve_ms, q)) if solve_ms.size else float("nan")

        sim_duration_s = self.last_t_s
        extra: dict[str, float] = {}
        if self.maneuver is not None:
            extra = maneuver_metrics(
                np.asarray(self.t_s), np.asarray(self.true_steer_rad),
                np.asarray(self.yaw_rate_radps), np.asarray(self.ay_mps2),
                np.asarray(self.speed_mps), self.maneuver)
        return {
            "cte_max_m": _max_abs(self.cte_m),
            "cte_rms_m": _rms(self.cte_m),
            "heading_err_max_rad": _max_abs(self.heading_err_rad),
            "heading_err_rms_rad": _rms(self.heading_err_rad),
            "speed_err_rms_mps": _rms(self.speed_err_mps),
            "steer_max_rad": _max_abs(self.steer_rad),
            "accel_max_mps2": float(accel.max()) if accel.size else float("nan"),
            "accel_min_mps2": float(accel.min()) if accel.size else float("nan"),
            "solve_ms_p50": percentile(50),
            "solve_ms_p99": percentile(99),
            "solve_ms_max": float(solve_ms.max()) if solve_ms.size else float("nan"),
            "solver_failures": self.solver_failures,
            "est_pos_rmse_m": _rms(self.pos_err_m),
            "est_yaw_rmse_rad": _rms(self.yaw_err_rad),
            "est_speed_rmse_mps": _rms(self.speed_est_err_mps),
            "nees_mean": float(np.mean(self.nees)) if self.nees else float("nan"),
            "nis_mean": float(np.mean(self.nis_per_dof)) if self.nis_per_dof else float("nan"),
            **{f"nis_{sensor}": self.nis_sum[sensor] / self.nis_dof[sensor]
               for sensor in sorted(self.nis_sum)},
            **{f"nis_dof_{sensor}": self.nis_dof[sensor] for sensor in sorted(self.nis_dof)},
            **rejection_counts(self.estimator_counts),
            "sim_duration_s": sim_duration_s,
            "wall_time_s": wall_time_s,
            "realtime_factor": sim_duration_s / wall_time_s if wall_time_s > 0 else float("nan"),
            "completed": completed,
            **extra,
        }
