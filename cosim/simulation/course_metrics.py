"""What the course checks while a run goes: ISO 3888-1 gates and a circuit's track limits.

* ``gates_hit``: how many of the ISO 3888-1 lanes (:mod:`tracker.paths.iso3888`) a corner
  of the car's body crossed a cone line of, and ``gate_<section>_passed`` for each lane.
* ``track_limit_exceedances``: how many times the car left the track: the body's edge (half
  the body width beside the true centre of gravity's projection on the centre line) went
  beyond the left or right half-width; one count per excursion, however long.

Both use the truth at the log rate, like the tracking metrics.
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

    def result(self) -> dict[str, int | bool]:
        values: dict[str, int | bool] = {}
        if self.course.gates:
            values["gates_hit"] = sum(self.hit.values())
            values.update({f"gate_{section}_passed": not hit
                           for section, hit in self.hit.items()})
        if self.course.bounds is not None:
            values["track_limit_exceedances"] = self.exceedances
        return values
