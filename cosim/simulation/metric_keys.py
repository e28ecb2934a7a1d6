"""Every metric key a run can emit: its unit, its meaning, what a good run gives, who emits it.

A run's metrics (``cosim inspect --json``'s ``metrics``, the ``/metrics`` topic, a sweep's
columns) are the union of what several observers compute at the end of the run; this table
is where each of their keys is declared, and ``docs/metrics.md`` is generated from it
(``python tools/metrics_doc.py``; a test fails when the file is stale, and another when a run
emits a key that is not here).

A family of keys is one row whose name holds a placeholder in angle brackets:
``nis_<sensor>`` stands for ``nis_gnss``, ``nis_imu`` ...; :data:`PLACEHOLDERS` says which
values each placeholder takes (a fixed list, or a pattern such as a lane section's number; a
new family, per lap say, adds its placeholder there).

To add a key: add a :class:`MetricKey` row to the group of the module that emits it (or a
new group, listed in :data:`METRICS`), with a placeholder for a family, then run
``python tools/metrics_doc.py``. Only the design's contract keys (:data:`METRIC_KEYS`) are
marked ``contract``: outside tests read them, so they are never renamed or dropped.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

from cosim.core.sensor_names import FUSED_SENSORS
from cosim.simulation.outcome import OUTCOMES, SEVERITY
from tracker.cruise.config import GAIN_NAMES

EVERY_RUN = "every run"
OPEN_LOOP = "open-loop manoeuvres (`steady-circle`, `step-steer`, `ramp-steer`)"
GATES = "courses with ISO 3888-1 gates (`iso-lane-change`)"
CIRCUIT = "circuits with track bounds (`track`, `path.file`)"
CLOSED = "closed paths (circuits: `track`, `generated-circuit`, a closed `path.file`)"
FRICTION_LIMITED = "friction-limited speed profiles (`path.speed_profile: friction-limited`)"
TRAFFIC = "runs with traffic (`traffic:`)"
ACC = "runs with the ACC (`tracker.acc.enabled`)"
WHEN_IT_HAPPENS = "runs where it happens"
REQUIREMENTS = "runs with STL requirements (`requirements:`, `--require`, `pass: {stl: ...}`)"

SCOPES = (EVERY_RUN, OPEN_LOOP, GATES, CIRCUIT, CLOSED, FRICTION_LIMITED, TRAFFIC, ACC,
          REQUIREMENTS, WHEN_IT_HAPPENS)
"""When a run has a key, in the order ``docs/metrics.md`` lists them."""

UNITS = ("m", "rad", "m/s", "m/s^2", "m/s^3", "rad/s", "1/s", "s", "ms", "%", "1", "count",
         "bool", "text")
"""Units a key may have: SI or the unit its name carries; ``1`` is a dimensionless ratio,
``count`` a whole number, ``bool`` true or false, ``text`` a string."""


@dataclass(frozen=True)
class Placeholder:
    """What a ``<name>`` in a key stands for."""

    values: tuple[str, ...]
    """The values it takes; empty when :attr:`pattern` says."""
    pattern: str = ""
    """A regular expression for values that are not a fixed list (a lap number)."""
    meaning: str = ""

    def regex(self) -> str:
        if self.values:
            return "(?:" + "|".join(re.escape(v) for v in self.values) + ")"
        return f"(?:{self.pattern})"


PLACEHOLDERS: Mapping[str, Placeholder] = MappingProxyType({
    "sensor": Placeholder(FUSED_SENSORS, meaning="a sensor the estimator fuses"),
    "kind": Placeholder(SEVERITY, meaning="an outcome event (`cosim.simulation.outcome`)"),
    "section": Placeholder((), r"[0-9]+", "an ISO 3888-1 lane section, from 1"),
    "gain": Placeholder(GAIN_NAMES, meaning="an ACC gain"),
    "lap": Placeholder((), r"[1-9][0-9]*", "a completed lap, from 1"),
    "index": Placeholder((), r"[0-9]+", "a requirement's place in `requirements:`, from 0"),
})
"""Every placeholder a key family may use."""


@dataclass(frozen=True)
class MetricKey:
    """One metric key (or a family of them, with a ``<placeholder>``)."""

    name: str
    unit: str
    meaning: str
    good: str
    """What a good run (or a consistent filter) gives; empty where no value is better."""
    emitter: str
    """The module that computes it."""
    scope: str = EVERY_RUN
    """Which runs have it (one of :data:`SCOPES`)."""
    contract: bool = False
    """One of :data:`METRIC_KEYS`: outside tests read it."""
    wall_clock: bool = False
    """It measures the machine, not the run: two runs of one seed differ in it."""
    values: tuple[str, ...] = ()
    """A ``text`` key's possible values, where they are a fixed list."""

    def __post_init__(self) -> None:
        if self.unit not in UNITS:
            raise ValueError(f"metric {self.name}: unit {self.unit!r} is not one of {UNITS}")
        if self.scope not in SCOPES:
            raise ValueError(f"metric {self.name}: scope {self.scope!r} is not one of {SCOPES}")
        for placeholder in re.findall(r"<([a-z_]+)>", self.name):
            if placeholder not in PLACEHOLDERS:
                raise ValueError(f"metric {self.name}: unknown placeholder <{placeholder}>")

    @property
    def is_family(self) -> bool:
        return "<" in self.name

    def regex(self) -> re.Pattern[str]:
        """The keys this row stands for."""
        parts = re.split(r"<([a-z_]+)>", self.name)
        text = "".join(re.escape(part) if i % 2 == 0 else PLACEHOLDERS[part].regex()
                       for i, part in enumerate(parts))
        return re.compile(text + r"\Z")


_METRICS = "cosim.simulation.metrics"
_RUNNER = "cosim.simulation.runner"
_COURSE = "cosim.simulation.course_metrics"
_MANOEUVRE = "cosim.simulation.manoeuvre_metrics"
_TRAFFIC = "cosim.simulation.traffic_loop"
_BELIEF = "cosim.simulation.belief_check"
_REQUIREMENTS = "cosim.simulation.requirements"
_HEALTH = "cosim.simulation.filter_health"

TRACKING = (
    MetricKey("cte_max_m", "m", "largest absolute lateral deviation of the true centre of "
              "gravity from the reference path, by projection onto the path (positive left)",
              "0", _METRICS, contract=True),
    MetricKey("cte_rms_m", "m", "RMS of that deviation over the log samples", "0", _METRICS,
              contract=True),
    MetricKey("heading_err_max_rad", "rad", "largest absolute true heading minus the path's "
              "heading at the projection, wrapped to (-pi, pi]", "0", _METRICS, contract=True),
    MetricKey("heading_err_rms_rad", "rad", "RMS of that heading error", "0", _METRICS,
              contract=True),
    MetricKey("speed_err_rms_mps", "m/s", "RMS of the true speed minus the reference speed "
              "at the projection and the time", "0", _METRICS, contract=True),
    MetricKey("speed_err_max_mps", "m/s", "largest absolute such speed error", "0", _METRICS),
    MetricKey("steer_max_rad", "rad", "largest absolute road-wheel angle commanded (as "
              "applied, after the delay line)", "", _METRICS, contract=True),
    MetricKey("accel_max_mps2", "m/s^2", "largest acceleration commanded", "", _METRICS,
              contract=True),
    MetricKey("accel_min_mps2", "m/s^2", "smallest (most braking) acceleration commanded",
              "", _METRICS, contract=True),
)

SOLVER = tuple(
    MetricKey(f"solve_ms_{stat}", "ms", f"{what} of the tracker's own solve time per control "
              "step (`Plan.solve_time_s`)", "", _METRICS, contract=True, wall_clock=True)
    for stat, what in (("p50", "median"), ("p99", "99th percentile"), ("max", "largest"))
) + (
    MetricKey("solver_failures", "count", "control steps whose plan is a fallback (the "
              "solver failed: shifted last plan or safe stop)", "0", _METRICS, contract=True),
    MetricKey("speed_reduced_steps", "count", "control steps whose plan slowed below the "
              "reference speed for grip (`Plan.speed_reduced`)", "0", _METRICS),
) + tuple(
    MetricKey(f"step_ms_{stat}", "ms", f"{what} of the wall time of the whole tracker step "
              "(everything the controller does per control period)", "", _METRICS,
              contract=True, wall_clock=True)
    for stat, what in (("p50", "median"), ("p99", "99th percentile"), ("max", "largest"))
)

ESTIMATION = (
    MetricKey("est_pos_rmse_m", "m", "RMS of the horizontal distance from the estimated to "
              "the true position", "0", _METRICS, contract=True),
    MetricKey("est_yaw_rmse_rad", "rad", "RMS of the estimated minus the true yaw", "0",
              _METRICS, contract=True),
    MetricKey("est_speed_rmse_mps", "m/s", "RMS of the estimated minus the true "
              "longitudinal speed", "0", _METRICS, contract=True),
    MetricKey("nees_mean", "1", "mean NEES over (x, y, yaw, v_x) at the log samples (the "
              "time average of one run: an ensemble judges consistency, "
              "`estimation.consistency`)", "4 (the 4 degrees of freedom)", _METRICS,
              contract=True),
    MetricKey("nis_mean", "1", "mean NIS per degree of freedom over every update the filter "
              "tested, gated ones included", "1", _METRICS, contract=True),
    MetricKey("nis_<sensor>", "1", "one sensor's summed NIS over its summed channels: NIS "
              "per degree of freedom (Bar-Shalom, Li, Kirubarajan 2001, sec. 5.4.2)", "1",
              _METRICS),
    MetricKey("nis_dof_<sensor>", "count", "the channels summed in `nis_<sensor>`", "",
              _METRICS),
    MetricKey("nis_settled_<sensor>", "1", "`nis_<sensor>` over the updates at or after the "
              "settling time (`estimation.consistency.SETTLE_S`, 1 s): the NIS per degree of "
              "freedom once the prior has converged", "1", _METRICS),
    MetricKey("nis_settled_dof_<sensor>", "count", "the channels summed in "
              "`nis_settled_<sensor>`", "", _METRICS),
    MetricKey("gated_first_s_<sensor>", "count", "the sensor's updates before the settling "
              "time that the gate refused in whole or in part", "0", _METRICS),
    MetricKey("tested_first_s_<sensor>", "count", "the sensor's updates before the settling "
              "time with a NIS, gated or not: of these a consistent filter's gate refuses a "
              "fraction `1 - estimator.gate_probability` by chance", "", _METRICS),
    MetricKey("updates_gated_<sensor>", "count", "the sensor's updates over the whole run "
              "that the gate refused in whole or in part", "0", _METRICS),
    MetricKey("updates_tested_<sensor>", "count", "the sensor's updates over the whole run "
              "with a NIS, gated or not", "", _METRICS),
    MetricKey("rejected_measurements", "count", "whole measurements the estimator refused, "
              "all causes", "0", _METRICS),
    MetricKey("rejected_gate", "count", "measurements the innovation gate refused", "0",
              _METRICS),
    MetricKey("rejected_nonfinite", "count", "measurements refused for a NaN or infinite "
              "value", "0", _METRICS),
    MetricKey("rejected_stale", "count", "measurements refused as older than the filter's "
              "time", "0", _METRICS),
    MetricKey("rejected_invalid", "count", "measurements refused as malformed (unknown "
              "channel, bad covariance)", "0", _METRICS),
    MetricKey("channels_gated", "count", "single channels the gate refused, also inside "
              "partly fused measurements", "0", _METRICS),
    MetricKey("estimator_surprises", "count", "ungated measurements far outside the gate, "
              "fused after the filter made room for a manoeuvre", "", _METRICS),
)

RUN = (
    MetricKey("sim_duration_s", "s", "simulated time the run reached", "the scenario's "
              "`sim.duration_s`", _METRICS, contract=True),
    MetricKey("wall_time_s", "s", "wall time of the run from its first step to its end (its "
              "set-up, where code may be compiled, is setup_time_s)", "", _METRICS,
              contract=True, wall_clock=True),
    MetricKey("realtime_factor", "1", "simulated time over wall time (wall_time_s): the "
              "simulation's speed, a first run's compile left out", "", _METRICS,
              contract=True, wall_clock=True),
    MetricKey("setup_time_s", "s", "wall time before the run's first step: models built, "
              "compiled code built or loaded, the log's header written", "", _RUNNER,
              wall_clock=True),
    MetricKey("completed", "bool", "the run reached its end without an abort", "true",
              _METRICS, contract=True),
    MetricKey("lat_accel_max_mps2", "m/s^2", "largest absolute lateral acceleration of the "
              "true centre of gravity (vehicle frame)", "", _METRICS),
    MetricKey("jerk_rms_mps3", "m/s^3", "RMS of the magnitude of the planar jerk (finite "
              "differences of the true vehicle-frame accelerations)", "", _METRICS),
    MetricKey("lat_jerk_rms_mps3", "m/s^3", "RMS of the lateral part of that jerk", "",
              _METRICS),
    MetricKey("faults_injected", "count", "sensor outputs the scenario's `faults:` changed",
              "", _RUNNER),
    MetricKey("outcome", "text", "how the run ended: `ok`, the most severe event or the "
              "abort, one of " + ", ".join(f"`{kind}`" for kind in OUTCOMES), "ok", _RUNNER,
              values=OUTCOMES),
    MetricKey("events", "count", "outcome events on `/events`", "0", _RUNNER),
    MetricKey("belief_mismatches", "count", "sensors whose NIS per degree of freedom left "
              "the band while the sensor's noise and the filter's belief about it differ "
              "(each one also a `belief_mismatch` line on `/events`; the outcome is "
              "unchanged)", "0", _BELIEF),
    MetricKey("filter_warnings", "count", "signs of an inconsistent filter at the end of "
              "the run: `nees_mean` above 2.5 x its 4 degrees of freedom, or a sensor's NIS "
              "per degree of freedom out of [0.3, 3] with its figure and belief alike (each "
              "a `filter_inconsistent` line on `/events` and a warning; the outcome is "
              "unchanged)", "0", _HEALTH),
    MetricKey("<kind>_t_s", "s", "simulated time of the first event of that kind", "",
              _RUNNER, scope=WHEN_IT_HAPPENS),
    MetricKey("abort_reason", "text", "why the run stopped early (`interrupted`, the error)",
              "", _RUNNER, scope=WHEN_IT_HAPPENS),
    MetricKey("stl_robustness_<index>", "1", "robustness of that STL requirement at t = 0, "
              "in its predicates' unit: >= 0 satisfied, < 0 violated by that much",
              ">= 0", _REQUIREMENTS, scope=REQUIREMENTS),
    MetricKey("stl_robustness", "1", "the smallest robustness of the run's STL requirements",
              ">= 0", _REQUIREMENTS, scope=REQUIREMENTS),
)

COURSE = (
    MetricKey("gates_hit", "count", "ISO 3888-1 lanes whose cone line a corner of the car's "
              "body crossed", "0", _COURSE, scope=GATES),
    MetricKey("gate_<section>_passed", "bool", "the car's body stayed within that lane's "
              "cones; ISO 3888-1 numbers the course's six sections in driving order and "
              "cones four: 1 (entry), 3 (side lane), 5 and 6 (exit), while 2 and 4 are the "
              "open zones of the lane changes", "true", _COURSE, scope=GATES),
    MetricKey("track_limit_exceedances", "count", "times the body's edge went beyond the "
              "track's left or right half-width (one per excursion)", "0", _COURSE,
              scope=CIRCUIT),
    MetricKey("laps_completed", "count", "laps the car covered (its progress along the path "
              "from where it started, over the lap length)", "", _COURSE, scope=CLOSED),
    MetricKey("lap_time_s", "s", "time of the first lap (NaN until one is completed)", "",
              _COURSE, scope=CLOSED),
    MetricKey("lap_<lap>_time_s", "s", "time of that lap (its ends interpolated between log "
              "samples)", "", _COURSE, scope=CLOSED),
    MetricKey("lap_<lap>_cte_max_m", "m", "largest absolute lateral deviation within that "
              "lap", "0", _COURSE, scope=CLOSED),
    MetricKey("lap_<lap>_lat_accel_max_mps2", "m/s^2", "largest absolute lateral "
              "acceleration of the true centre of gravity within that lap", "at most "
              "`profile_lat_accel_max_mps2`", _COURSE, scope=CLOSED),
    MetricKey("profile_lat_accel_max_mps2", "m/s^2", "the lateral limit the speed profile "
              "was built with (`cosim.simulation.course.profile_limits`), to hold "
              "`lat_accel_max_mps2` against", "", _COURSE, scope=FRICTION_LIMITED),
)

MANOEUVRE = (
    MetricKey("steady_speed_mps", "m/s", "mean true speed over the final "
              "`manoeuvre.steady_window_s`", "", _MANOEUVRE, scope=OPEN_LOOP),
    MetricKey("steady_steer_rad", "rad", "mean true road-wheel angle over that window", "",
              _MANOEUVRE, scope=OPEN_LOOP),
    MetricKey("steady_yaw_rate_radps", "rad/s", "mean true yaw rate over that window", "",
              _MANOEUVRE, scope=OPEN_LOOP),
    MetricKey("steady_ay_mps2", "m/s^2", "mean true lateral acceleration over that window",
              "", _MANOEUVRE, scope=OPEN_LOOP),
    MetricKey("steady_radius_m", "m", "steady speed over steady yaw rate (ISO 4138)", "",
              _MANOEUVRE, scope=OPEN_LOOP),
    MetricKey("steady_yaw_rate_gain_1ps", "1/s", "steady yaw rate over steady road-wheel "
              "angle", "", _MANOEUVRE, scope=OPEN_LOOP),
    MetricKey("yaw_rate_response_time_s", "s", "step steer: from 50 % of the steering input "
              "to 90 % of the steady yaw rate (ISO 7401)", "", _MANOEUVRE, scope=OPEN_LOOP),
    MetricKey("yaw_rate_overshoot", "1", "step steer: peak yaw rate over the steady one, "
              "minus one (ISO 7401)", "", _MANOEUVRE, scope=OPEN_LOOP),
    MetricKey("ay_max_mps2", "m/s^2", "ramp steer: largest lateral acceleration after a "
              "0.5 s moving average (the grip limit)", "", _MANOEUVRE, scope=OPEN_LOOP),
)

TRAFFIC_KEYS = (
    MetricKey("gap_min_m", "m", "smallest true gap to the car ahead in the ego's lane "
              "(negative once the bumpers overlap)", "> 0", _TRAFFIC, scope=TRAFFIC),
    MetricKey("time_gap_min_s", "s", "smallest gap over the ego's speed (above 1 m/s)", "",
              _TRAFFIC, scope=TRAFFIC),
    MetricKey("ttc_min_s", "s", "smallest time to collision, gap over closing speed (while "
              "closing)", "", _TRAFFIC, scope=TRAFFIC),
    MetricKey("safe_gap_margin_min_m", "m", "smallest gap minus the minimum safe gap "
              "`tracker.acc.safe_standstill_gap_m + safe_time_gap_s v`", ">= 0", _TRAFFIC,
              scope=TRAFFIC),
    MetricKey("safe_gap_ok", "bool", "the gap never fell below the minimum safe gap", "true",
              _TRAFFIC, scope=TRAFFIC),
)

ACC_KEYS = (
    MetricKey("acc_speed_err_rms_mps", "m/s", "RMS of the true speed minus the set speed in "
              "speed mode", "0", _TRAFFIC, scope=ACC),
    MetricKey("acc_speed_err_final_mps", "m/s", "the last such speed error", "0", _TRAFFIC,
              scope=ACC),
    MetricKey("acc_set_speed_t_s", "s", "first time within 0.5 m/s of the set speed", "",
              _TRAFFIC, scope=ACC),
    MetricKey("acc_gap_mode_t_s", "s", "first switch to gap mode", "", _TRAFFIC, scope=ACC),
    MetricKey("acc_gap_mode_s", "s", "time spent in gap mode", "", _TRAFFIC, scope=ACC),
    MetricKey("acc_objective_mean", "1", "mean of the objective extremum seeking minimises, "
              "every control step (docs/acc.md)", "", _TRAFFIC, scope=ACC),
    MetricKey("acc_objective_gap_mean", "1", "mean objective over the gap-mode steps", "",
              _TRAFFIC, scope=ACC),
    MetricKey("acc_objective_steady_mean", "1", "mean objective over the steady gap-keeping "
              "steps (`|gap error| < tracker.acc.esc.max_gap_error_m`): the figure to "
              "compare tunings by", "", _TRAFFIC, scope=ACC),
    MetricKey("acc_objective_final_mean", "1", "mean objective over the run's last "
              "`tracker.acc.esc.settle_window_s`", "", _TRAFFIC, scope=ACC),
    MetricKey("acc_k_v", "1", "final estimate of the speed-error gain", "", _TRAFFIC,
              scope=ACC),
    MetricKey("acc_k_x", "1", "final estimate of the gap-error gain", "", _TRAFFIC,
              scope=ACC),
    MetricKey("acc_k_vrel", "1", "final estimate of the relative-speed gain", "", _TRAFFIC,
              scope=ACC),
    MetricKey("acc_<gain>_drift_pct", "%", "range of that gain's estimate over the last "
              "`tracker.acc.esc.settle_window_s`, in percent of its final value (NaN without "
              "extremum seeking)", "small", _TRAFFIC, scope=ACC),
    MetricKey("esc_gain_drift_pct", "%", "the largest of the three gain drifts", "small",
              _TRAFFIC, scope=ACC),
    MetricKey("esc_gains_settled", "bool", "that drift is at most "
              "`tracker.acc.esc.settle_tolerance_pct`", "true", _TRAFFIC, scope=ACC),
    MetricKey("acc_targets", "text", "the range sensor's targets in order of appearance, "
              "comma-separated", "", _TRAFFIC, scope=ACC),
    MetricKey("acc_target_changes", "count", "times the range sensor's target changed", "",
              _TRAFFIC, scope=ACC),
)

METRICS: tuple[MetricKey, ...] = (
    *TRACKING, *SOLVER, *ESTIMATION, *RUN, *COURSE, *MANOEUVRE, *TRAFFIC_KEYS, *ACC_KEYS)
"""Every metric key, in the order ``docs/metrics.md`` lists them within a scope."""

_BY_NAME: Mapping[str, MetricKey] = MappingProxyType(
    {key.name: key for key in METRICS if not key.is_family})
_FAMILIES: tuple[tuple[re.Pattern[str], MetricKey], ...] = tuple(
    (key.regex(), key) for key in METRICS if key.is_family)

METRIC_KEYS: tuple[str, ...] = (
    "cte_max_m", "cte_rms_m", "heading_err_max_rad", "heading_err_rms_rad",
    "speed_err_rms_mps", "steer_max_rad", "accel_max_mps2", "accel_min_mps2",
    "solve_ms_p50", "solve_ms_p99", "solve_ms_max", "solver_failures",
    "est_pos_rmse_m", "est_yaw_rmse_rad", "est_speed_rmse_mps", "nees_mean", "nis_mean",
    "sim_duration_s", "wall_time_s", "realtime_factor", "completed",
    "step_ms_p50", "step_ms_p99", "step_ms_max",
)
"""The contract's keys, every run has them (outside tests read them; never renamed). The
order is the one sweep tables show them in; a test checks it against the rows marked
``contract``."""

WALL_CLOCK_KEYS: tuple[str, ...] = tuple(key.name for key in METRICS if key.wall_clock)
"""Metrics that measure the machine, not the run: they differ between two runs of one seed."""


def metric_key(name: str) -> MetricKey | None:
    """The row that declares the key ``name`` (a family's row for ``nis_gnss``), or None."""
    row = _BY_NAME.get(name)
    if row is not None:
        return row
    for pattern, family in _FAMILIES:
        if pattern.match(name):
            return family
    return None


def undocumented(names: Iterable[str]) -> list[str]:
    """The keys among ``names`` that no row declares, sorted."""
    return sorted(name for name in names if metric_key(name) is None)


def unit_of(name: str) -> str:
    """The unit of a declared key; ``-`` for one that is not declared."""
    row = metric_key(name)
    return row.unit if row is not None else "-"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def markdown() -> str:
    """``docs/metrics.md``: every key, by the runs that have it, with unit and meaning."""
    lines = [
        "# Metric keys",
        "",
        "Generated from `cosim/simulation/metric_keys.py` by `python tools/metrics_doc.py`:",
        "edit the table there, not this file. A run's metrics are printed by `cosim run`,",
        "stored on the log's `/metrics` topic and metadata, and shown by",
        "`cosim inspect --json` (its `metrics` member). Keys marked * are the contract",
        "(every run has them; outside tests read them). Wall-clock keys (solve and step",
        "times, wall time, real-time factor) differ between two runs of one seed; every",
        "other key is the same, bit for bit.",
        "",
        "A key with a `<placeholder>` is a family:",
        "",
        "| placeholder | stands for | values |",
        "|---|---|---|",
    ]
    for name, placeholder in PLACEHOLDERS.items():
        values = ", ".join(f"`{v}`" for v in placeholder.values) or \
            f"`{placeholder.pattern}`"
        lines.append(f"| `<{name}>` | {placeholder.meaning} | {values} |")
    for scope in SCOPES:
        rows = [key for key in METRICS if key.scope == scope]
        lines += ["", f"## {scope[0].upper()}{scope[1:]}", "",
                  "| key | unit | meaning | a good run | emitted by |", "|---|---|---|---|---|"]
        for key in rows:
            star = "*" if key.contract else ""
            lines.append(f"| `{key.name}`{star} | {key.unit} | {_cell(key.meaning)} | "
                         f"{_cell(key.good)} | `{key.emitter}` |")
    return "\n".join(lines) + "\n"
