"""Traffic in a run: the range sensor, collisions and the gap and ACC metrics.

The runner builds a :class:`TrafficLoop` when the scenario has traffic (``traffic:``) and
calls it from its phases; what only looks (the log: :class:`cosim.simulation.traffic_log.
TrafficLog`) is one of its ``observers``, called at each point below; a run without a log
has none and builds no message:

- at each log step (:meth:`TrafficLoop.log`): the cars' true poses (``cars``); the true gap
  to the nearest car ahead in the ego's lane, its time gap, time to collision and the
  minimum safe gap (``gap``, and into the metrics); a contact between the ego's body and a
  car's ends the run (:class:`CollisionError`: outcome ``collision``, ``completed: false``);
- when the range sensor is due (:meth:`TrafficLoop.sense`): a reading (``ranged``),
  delivered to the tracker if it takes readings (the ACC: ``observe_range``);
- after each control step (:meth:`TrafficLoop.after_control`): the ACC's decision
  (``decided``: its gains, objective and mode, which Foxglove plots converge).

Metrics (:meth:`TrafficLoop.result`, from the truth unless named otherwise):
``gap_min_m`` (smallest true gap to the car ahead in the lane, :meth:`TrafficLoop.car_ahead`;
negative once the bumpers overlap), ``time_gap_min_s`` (gap
over the ego's speed, above 1 m/s), ``ttc_min_s`` (gap over closing speed, when closing),
``safe_gap_margin_min_m`` (smallest gap minus the minimum safe gap ``d_safe + h_safe v``,
``tracker.acc.safe_*``), ``safe_gap_ok``; with the ACC: ``acc_speed_err_rms_mps`` (true speed
minus the set speed while in speed mode), ``acc_speed_err_final_mps`` (the last such
sample), ``acc_set_speed_t_s`` (first time within 0.5 m/s of the set speed),
``acc_gap_mode_t_s`` (first switch to gap mode) and ``acc_gap_mode_s`` (time in it),
``acc_objective_mean`` (mean of the objective ESC minimises, every control step) and
``acc_objective_gap_mean`` (over the gap-mode steps) and ``acc_objective_steady_mean``
(over the gap-mode steps in the steady regime ESC tunes in, ``|gap error| <
tracker.acc.esc.max_gap_error_m``: the figure to compare tunings by), ``acc_k_v``, ``acc_k_x``,
``acc_k_vrel`` (the final gain estimates), ``acc_targets`` (the range sensor's targets in
order of appearance, comma-separated) and ``acc_target_changes``.

Whether extremum seeking has settled is judged over the run's last ``W =
tracker.acc.esc.settle_window_s`` seconds (:class:`GainSettling`): ``acc_<gain>_drift_pct``
is the range (largest minus smallest) of that gain's estimate over the window, in percent of
its final value, and ``esc_gain_drift_pct`` the largest of the three; ``esc_gains_settled``
is true when that is at most ``tracker.acc.esc.settle_tolerance_pct``. A range, not the
change from the window's start to its end, so that a gain oscillating about a value does not
pass for settled. NaN (and not settled) without ESC or in a run shorter than the window.
``acc_objective_final_mean`` is the mean objective over the same window, with or without
ESC (the figure to compare fixed gains with tuned ones once tuning is over).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from cosim.core.records import VehicleState
from cosim.core.traffic_records import CarPose
from cosim.plant.car import MujocoPlant
from cosim.plant.traffic import Traffic, traffic_cars
from cosim.sensing.range_sensor import RangeSensor
from cosim.simulation.running_stats import RunningStats
from cosim.simulation.scenario_config import ScenarioConfig, steps_per_period
from cosim.simulation.traffic_log import TrafficObserver
from tracker.cruise.config import GAIN_NAMES
from tracker.protocol import RangeObserver

SET_SPEED_TOLERANCE_MPS = 0.5
"""The set speed counts as reached within this [m/s]."""

MIN_SPEED_FOR_TIME_GAP_MPS = 1.0
"""Below this speed the time gap (gap / speed) is not computed [m/s]."""

MIN_CLOSING_SPEED_MPS = 0.1
"""Time to collision is computed only when closing faster than this [m/s]."""


class GainSettling:
    """The gain estimates and objective of the last ``window_s`` seconds of control steps, and
    how far each gain moved over them (module docstring)."""

    def __init__(self, window_s: float) -> None:
        self.window_s = window_s
        self._rows: deque[tuple[float, tuple[float, ...], float]] = deque()
        self._first_t_s = math.nan

    def add(self, t_s: float, estimates: tuple[float, ...], objective: float) -> None:
        if math.isnan(self._first_t_s):
            self._first_t_s = t_s
        rows = self._rows
        rows.append((t_s, estimates, objective))
        while rows and rows[0][0] < t_s - self.window_s:
            rows.popleft()

    @property
    def full(self) -> bool:
        """Whether the steps seen span the whole window."""
        return bool(self._rows) and self._rows[-1][0] - self._first_t_s >= self.window_s

    def drift_pct(self) -> tuple[float, ...]:
        """Each gain's range over the window in percent of its final value (NaN: not full)."""
        if not self.full:
            return (math.nan,) * len(self._rows[0][1]) if self._rows else ()
        values = np.array([estimates for _, estimates, _ in self._rows])
        final = np.abs(values[-1])
        with np.errstate(divide="ignore", invalid="ignore"):
            return tuple(float(v) for v in 100.0 * np.ptp(values, axis=0) / final)

    def objective_mean(self) -> float:
        """Mean finite objective over the window (NaN: not full)."""
        objectives = [j for _, _, j in self._rows if math.isfinite(j)]
        return float(np.mean(objectives)) if self.full and objectives else math.nan


class CollisionError(Exception):
    """The ego car touched a traffic car: the run ends with outcome ``collision``."""

    def __init__(self, car: str, t_s: float) -> None:
        super().__init__(f"collision with traffic car {car!r} at t = {t_s:.3f} s")
        self.car = car
        self.t_s = t_s


def build_traffic(config: ScenarioConfig) -> Traffic | None:
    """The scenario's traffic for the plant, or None without a ``traffic:`` section."""
    if not config.traffic:
        return None
    return Traffic(traffic_cars(config.traffic), config.initial)


class TrafficLoop:
    """The run's traffic phases (module docstring)."""

    def __init__(self, config: ScenarioConfig, plant: MujocoPlant, traffic: Traffic,
                 tracker: object, rng: np.random.Generator) -> None:
        self.config = config
        self.plant = plant
        self.traffic = traffic
        self.observers: tuple[TrafficObserver, ...] = ()
        """Called at the points of the traffic's part of a step (the log, when the run has
        one: :class:`cosim.simulation.traffic_log.TrafficLog`)."""
        from tracker.cruise.law import AccTracker  # only runs with traffic need the ACC's code

        self.acc = tracker if isinstance(tracker, AccTracker) else None
        self.deliver = tracker.observe_range if isinstance(tracker, RangeObserver) else None
        radar = config.sensors.radar
        self.radar = RangeSensor(radar, traffic.ego_front_m) if radar.enabled else None
        self.radar_steps = steps_per_period(radar.period_s, config.sim.physics_dt_s,
                                            "sensors.radar.period_s")
        self.rng = rng
        """The range sensor's own generator (the runner's ``component_rng``)."""
        self.lane_half_width_m = radar.lane_half_width_m
        acc = config.tracker.acc
        self.safe_standstill_gap_m = acc.safe_standstill_gap_m
        self.safe_time_gap_s = acc.safe_time_gap_s
        self.set_speed_mps = acc.set_speed_mps
        self.gap_m = RunningStats()
        self.time_gap_s = RunningStats()
        self.ttc_s = RunningStats()
        self.safe_margin_m = RunningStats()
        self.speed_err_mps = RunningStats()
        self.objective = RunningStats()
        self.objective_gap = RunningStats()
        self.objective_steady = RunningStats()
        self.steady_gap_error_m = acc.esc.max_gap_error_m
        self.settling = GainSettling(acc.esc.settle_window_s)
        self.settle_tolerance_pct = acc.esc.settle_tolerance_pct
        self.set_speed_t_s = math.nan
        self.gap_mode_t_s = math.nan
        self.gap_mode_steps = 0
        self.mode = "speed"
        self.targets: list[str] = []
        self.target_changes = 0
        self.last_target = ""

    def log(self, t_s: float, truth: VehicleState, scene: bool = True) -> None:
        """Log step: poses, the scene (when ``scene``: at ``sim.scene_period_s``), the true
        gap and its metrics; raise on a collision."""
        poses = self.traffic.poses(t_s)
        observers = self.observers
        for observer in observers:
            observer.cars(t_s, poses, scene, self.last_target)
        car, gap, range_rate = self.car_ahead(truth, poses)
        speed = truth.vx_mps
        safe_gap = self.safe_standstill_gap_m + self.safe_time_gap_s * max(speed, 0.0)
        time_gap = ttc = math.nan
        if car is not None:
            self.gap_m.add(gap)
            self.safe_margin_m.add(gap - safe_gap)
            touching_gap = max(gap, 0.0)  # overlapping bumpers: the collision step
            if speed > MIN_SPEED_FOR_TIME_GAP_MPS:
                time_gap = touching_gap / speed
                self.time_gap_s.add(time_gap)
            if -range_rate > MIN_CLOSING_SPEED_MPS:
                ttc = touching_gap / -range_rate
                self.ttc_s.add(ttc)
        for observer in observers:
            observer.gap(t_s, car, gap, range_rate, time_gap, ttc, safe_gap)
        if self.acc is not None and t_s > 0.0:
            if self.mode == "speed":
                self.speed_err_mps.add(truth.speed_mps - self.set_speed_mps)
            if math.isnan(self.set_speed_t_s) and \
                    abs(truth.speed_mps - self.set_speed_mps) <= SET_SPEED_TOLERANCE_MPS:
                self.set_speed_t_s = t_s
        hit = self.traffic.collision(self.plant.data)
        if hit:
            raise CollisionError(hit, t_s)

    def car_ahead(self, truth: VehicleState,
                  poses: tuple[CarPose, ...]) -> tuple[CarPose | None, float, float]:
        """The true nearest car ahead in the ego's lane, in the cars' lane frame (the road's,
        not the ego's heading: a small heading error at 400 m is metres sideways): (car, gap
        from the ego's front bumper to its rear [m], its speed minus the ego's along the
        lane [m/s])."""
        traffic = self.traffic
        ego_along, ego_offset = traffic.lane_coordinates(truth.x_m, truth.y_m)
        lane_yaw = traffic.lane_yaw_rad
        ego_front = ego_along + traffic.ego_front_m * math.cos(truth.yaw_rad - lane_yaw)
        ego_speed = truth.vx_mps * math.cos(truth.yaw_rad - lane_yaw)
        best: tuple[CarPose | None, float, float] = (None, math.nan, math.nan)
        for pose in poses:
            along, offset = traffic.lane_coordinates(pose.x_m, pose.y_m)
            relative_yaw = pose.yaw_rad - lane_yaw
            gap = along - 0.5 * pose.length_m * math.cos(relative_yaw) - ego_front
            if along <= ego_along or abs(offset - ego_offset) > self.lane_half_width_m:
                continue
            if best[0] is None or gap < best[1]:
                best = (pose, gap, pose.speed_mps * math.cos(relative_yaw) - ego_speed)
        return best

    @property
    def periods(self) -> tuple[int, ...]:
        """The physics steps between the instants traffic has work of its own (the range
        sensor's samples); the cars' poses follow every physics step inside the plant."""
        return (self.radar_steps,) if self.radar is not None else ()

    def radar_due(self, k: int) -> bool:
        """Whether the range sensor samples at physics step ``k``."""
        return self.radar is not None and k % self.radar_steps == 0

    def sense(self, t_s: float, truth: VehicleState) -> None:
        """Sample the range sensor (due now: :meth:`radar_due`) and hand the reading to
        the tracker."""
        if self.radar is None:
            return
        reading = self.radar.sample(truth, self.traffic.poses(t_s), self.rng)
        if reading is None:  # a dropout: nothing is delivered
            return
        for observer in self.observers:
            observer.ranged(t_s, reading)
        if reading.target and reading.target != self.last_target:
            if self.last_target:
                self.target_changes += 1
            if reading.target not in self.targets:
                self.targets.append(reading.target)
            self.last_target = reading.target
        if self.deliver is not None:
            self.deliver(reading)

    def after_control(self, t_s: float) -> None:
        """The ACC's decision of this control step: to the observers, into the metrics."""
        status = self.acc.status if self.acc is not None else None
        if status is None:
            return
        for observer in self.observers:
            observer.decided(t_s, status)
        self.mode = status.mode
        self.settling.add(t_s, status.gain_estimates, status.objective)
        if math.isfinite(status.objective):
            self.objective.add(status.objective)
        if status.mode == "gap":
            self.gap_mode_steps += 1
            if math.isfinite(status.objective):
                self.objective_gap.add(status.objective)
                if abs(status.gap_m - status.desired_gap_m) < self.steady_gap_error_m:
                    self.objective_steady.add(status.objective)
            if math.isnan(self.gap_mode_t_s):
                self.gap_mode_t_s = t_s

    def result(self) -> dict[str, float | int | bool | str]:
        values: dict[str, float | int | bool | str] = {
            "gap_min_m": self.gap_m.minimum,
            "time_gap_min_s": self.time_gap_s.minimum,
            "ttc_min_s": self.ttc_s.minimum,
            "safe_gap_margin_min_m": self.safe_margin_m.minimum,
            "safe_gap_ok": bool(self.safe_margin_m.count == 0
                                or self.safe_margin_m.minimum >= 0.0),
        }
        if self.acc is None:
            return values
        status = self.acc.status
        estimates = status.gain_estimates if status is not None else (math.nan,) * 3
        drifts = self.settling.drift_pct() if self.acc.seeker is not None else ()
        if len(drifts) != len(GAIN_NAMES):
            drifts = (math.nan,) * len(GAIN_NAMES)
        drift = max(drifts) if not any(math.isnan(d) for d in drifts) else math.nan
        values.update({
            "acc_speed_err_rms_mps": self.speed_err_mps.rms,
            "acc_speed_err_final_mps": self.speed_err_mps.last,
            "acc_set_speed_t_s": self.set_speed_t_s,
            "acc_gap_mode_t_s": self.gap_mode_t_s,
            "acc_gap_mode_s": self.gap_mode_steps * self.acc.period_s,
            "acc_objective_mean": self.objective.mean,
            "acc_objective_gap_mean": self.objective_gap.mean,
            "acc_objective_steady_mean": self.objective_steady.mean,
            "acc_k_v": estimates[0], "acc_k_x": estimates[1], "acc_k_vrel": estimates[2],
            "acc_targets": ",".join(self.targets),
            "acc_target_changes": self.target_changes,
            **{f"acc_{name}_drift_pct": value
               for name, value in zip(GAIN_NAMES, drifts, strict=True)},
            "esc_gain_drift_pct": drift,
            "esc_gains_settled": bool(drift <= self.settle_tolerance_pct),
            "acc_objective_final_mean": self.settling.objective_mean(),
        })
        return values
