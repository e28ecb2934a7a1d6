"""What the course checks while a run goes: ISO 3888-1 gates and a circuit's track limits.

* ``gates_hit``: how many of the ISO 3888-1 lanes (:mod:`tracker.paths.iso3888`) a corner
  of the car's body crossed a cone line of, and ``gate_<section>_passed`` for each lane.
* ``track_limit_exceedances``: how many times the car left the track: the body's edge (half
  the body width beside the true centre of gravity's projection on the centre line) went
  beyond the left or right half-width; one count per excursion, however long.

* on a closed path (a circuit), lap times: the car's progress along the path (its
  projection's arc length, unwrapped) from where it started; each time it has covered one
  more lap length, a lap ends (the time interpolated between the two log samples around
  it). ``laps_completed``, ``lap_time_s`` (the first lap; NaN until one is completed) and,
  per lap ``n`` from 1, ``lap_<n>_time_s``, ``lap_<n>_cte_max_m`` and
  ``lap_<n>_lat_accel_max_mps2`` (largest absolute lateral acceleration of the true CoG).
* ``profile_lat_accel_max_mps2``: the lateral limit a friction-limited speed profile was
  built with (:func:`cosim.simulation.course.profile_limits`), to hold
  ``lat_accel_max_mps2`` against.

All use the truth at the log rate, like the tracking metrics.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cosim.core.records import VehicleState
from cosim.core.vehicle_params import CarParams
from cosim.log.foxglove import FRONT_OVERHANG_M, REAR_OVERHANG_M
from cosim.simulation.course import Course, body_width_m
from tracker.paths.iso3888 import corners, gate_hit


@dataclass
class CourseMonitor:
    """Gate hits and track-limit excursions of the true car on a :class:`Course`."""

    course: Course
    vehicle: CarParams
    hit: dict[int, bool] = field(default_factory=dict)
    exceedances: int = 0
    outside: bool = False
    laps: list[tuple[float, float, float]] = field(default_factory=list)
    """Per completed lap: time, max |CTE|, max |lateral acceleration|."""
    _progress_m: float | None = None
    _last: tuple[float, float] = (0.0, 0.0)
    """``(t_s, s_m)`` of the last sample."""
    _lap_start_s: float = 0.0
    _lap_cte_m: float = 0.0
    _lap_lat_accel_mps2: float = 0.0

    def __post_init__(self) -> None:
        self.hit = {gate.section: False for gate in self.course.gates}

    def add_truth(self, truth: VehicleState, lateral_error_m: float, s_m: float) -> None:
        """One log sample: the true pose and its projection on the path."""
        half_width = body_width_m(self.vehicle) / 2.0
        if self.course.gates:
            body = corners(truth.x_m, truth.y_m, truth.yaw_rad,
                           self.vehicle.cog_front_m + FRONT_OVERHANG_M,
                           self.vehicle.cog_rear_m + REAR_OVERHANG_M, half_width)
            for gate in self.course.gates:
                if not self.hit[gate.section] and gate_hit(gate, body):
                    self.hit[gate.section] = True
        bounds = self.course.bounds
        if bounds is not None:
            reference = self.course.reference
            left, right = bounds.at(s_m, reference.length_m if reference.closed else None)
            outside = (lateral_error_m + half_width > left
                       or -lateral_error_m + half_width > right)
            if outside and not self.outside:
                self.exceedances += 1
            self.outside = outside
        if self.course.reference.closed:
            self._count_laps(truth, lateral_error_m, s_m)

    def _count_laps(self, truth: VehicleState, lateral_error_m: float, s_m: float) -> None:
        lap_m = self.course.reference.length_m
        if self._progress_m is None:  # the start: a hair behind the line is behind it
            self._progress_m = s_m - lap_m if s_m > lap_m / 2.0 else s_m
            self._last = (truth.t_s, s_m)
            return
        last_t, last_s = self._last
        step = s_m - last_s
        step += lap_m if step < -lap_m / 2.0 else -lap_m if step > lap_m / 2.0 else 0.0
        before = self._progress_m
        self._progress_m = before + step
        self._lap_cte_m = max(self._lap_cte_m, abs(lateral_error_m))
        if truth.t_s > 0.0:  # the plant has no acceleration before its first step
            self._lap_lat_accel_mps2 = max(self._lap_lat_accel_mps2, abs(truth.ay_mps2))
        target = (len(self.laps) + 1) * lap_m
        if before < target <= self._progress_m and step > 0.0:
            t_end = last_t + (truth.t_s - last_t) * (target - before) / step
            self.laps.append((t_end - self._lap_start_s, self._lap_cte_m,
                              self._lap_lat_accel_mps2))
            self._lap_start_s, self._lap_cte_m, self._lap_lat_accel_mps2 = t_end, 0.0, 0.0
        self._last = (truth.t_s, s_m)

    def result(self) -> dict[str, int | bool | float]:
        values: dict[str, int | bool | float] = {}
        if self.course.gates:
            values["gates_hit"] = sum(self.hit.values())
            values.update({f"gate_{section}_passed": not hit
                           for section, hit in self.hit.items()})
        if self.course.bounds is not None:
            values["track_limit_exceedances"] = self.exceedances
        if self.course.limits is not None:
            values["profile_lat_accel_max_mps2"] = self.course.limits.lat_accel_max_mps2
        if self.course.reference.closed:
            values["laps_completed"] = len(self.laps)
            values["lap_time_s"] = self.laps[0][0] if self.laps else float("nan")
            for n, (time_s, cte_m, lat_accel) in enumerate(self.laps, start=1):
                values[f"lap_{n}_time_s"] = time_s
                values[f"lap_{n}_cte_max_m"] = cte_m
                values[f"lap_{n}_lat_accel_max_mps2"] = lat_accel
        return values
