"""A forward range sensor on the ego car (radar-like): gap and range rate to the car ahead.

At each sample it looks at every traffic car from its mounting point, the centre of the
ego's front bumper (``front_m`` ahead of the centre of gravity, on the ego's x axis): a car
is a candidate when the nearest point of its rear (its centre minus half its length along
its heading) lies ahead, inside the field of view (``|bearing| <= fov_rad / 2``), within
``max_range_m``, and its centre is in the ego's lane (``|lateral offset in the ego frame|
<= lane_half_width_m``). The nearest candidate is the target; its gap (the rear's distance
ahead along the ego's heading) and range rate (its velocity along the ego's heading minus
the ego's forward speed) get white Gaussian noise. With probability ``dropout_probability``
a sample is lost (nothing is delivered). The target's name is part of the reading, so a
car cutting in shows as a change of target (a real radar's track identifier).

The lane is the ego's x axis, straight ahead (no course prediction from the yaw rate): at
long range a small heading error moves a car out of it (0.005 rad at 350 m is 1.75 m), so a
target far ahead can flicker in and out until the ego is closer; the metrics judge the gap
in the road's lane frame instead (:mod:`cosim.simulation.traffic_loop`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cosim.core.config_fields import setting
from cosim.core.records import VehicleState
from cosim.core.sensor_names import RADAR
from cosim.core.traffic_records import CarPose, RangeReading


@dataclass(frozen=True)
class RadarConfig:
    """Forward range sensor (used by the ACC, not by the state estimator)."""

    enabled: bool = setting(True, doc="sampled only when the scenario has traffic")
    period_s: float = setting(0.05, low=0.001, high=10.0)
    gap_sigma_m: float = setting(0.2, low=0.0, high=100.0, doc="gap noise")
    range_rate_sigma_mps: float = setting(0.1, low=0.0, high=100.0, doc="range-rate noise")
    max_range_m: float = setting(200.0, low=1.0, high=1e4)
    fov_rad: float = setting(0.35, low=0.01, high=6.2832, doc="full field of view (20 deg)")
    lane_half_width_m: float = setting(1.75, low=0.1, high=50.0,
                                       doc="a car whose centre is within this of the ego's "
                                       "x axis is in the ego's lane")
    dropout_probability: float = setting(0.0, low=0.0, high=1.0,
                                         doc="chance that a sample is lost")


class RangeSensor:
    """Samples :class:`RangeReading`s of the cars around the ego (module docstring)."""

    name = RADAR

    def __init__(self, config: RadarConfig, front_m: float) -> None:
        self.config = config
        self.period_s = config.period_s
        self.front_m = front_m

    def true_target(self, ego: VehicleState,
                    cars: Sequence[CarPose]) -> tuple[CarPose | None, float, float]:
        """The target car without noise: (car or None, gap [m], range rate [m/s])."""
        c = self.config
        cos_yaw, sin_yaw = math.cos(ego.yaw_rad), math.sin(ego.yaw_rad)
        sensor_x = ego.x_m + self.front_m * cos_yaw
        sensor_y = ego.y_m + self.front_m * sin_yaw
        best: tuple[CarPose | None, float, float] = (None, math.nan, math.nan)
        for car in cars:
            dx, dy = car.x_m - sensor_x, car.y_m - sensor_y
            ahead = dx * cos_yaw + dy * sin_yaw
            lateral = -dx * sin_yaw + dy * cos_yaw
            relative_yaw = car.yaw_rad - ego.yaw_rad
            gap = ahead - 0.5 * car.length_m * math.cos(relative_yaw)
            if gap <= 0.0 or gap > c.max_range_m or abs(lateral) > c.lane_half_width_m:
                continue
            if abs(math.atan2(lateral, gap)) > 0.5 * c.fov_rad:
                continue
            if best[0] is None or gap < best[1]:
                range_rate = car.speed_mps * math.cos(relative_yaw) - ego.vx_mps
                best = (car, gap, range_rate)
        return best

    def sample(self, ego: VehicleState, cars: Sequence[CarPose],
               rng: np.random.Generator) -> RangeReading | None:
        """One noisy reading, or None when the sample drops out."""
        c = self.config
        # Draw every random number every sample, so a dropout or a target change does not
        # shift the noise of later samples.
        lost, gap_noise, rate_noise = rng.random(), rng.standard_normal(), rng.standard_normal()
        if lost < c.dropout_probability:
            return None
        car, gap, range_rate = self.true_target(ego, cars)
        if car is None:
            return RangeReading(ego.t_s, "", math.nan, math.nan)
        return RangeReading(ego.t_s, car.name, gap + c.gap_sigma_m * gap_noise,
                            range_rate + c.range_rate_sigma_mps * rate_noise)
