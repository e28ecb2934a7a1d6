"""Traffic: other cars in the scene, driven by scripted speed and lane profiles.

Each car (``traffic.<name>`` in a scenario) drives along a line parallel to the ego car's
initial heading: it starts ``gap_m`` ahead of the ego's initial centre of gravity and
``lateral_offset_m`` to its left, and follows a speed profile (``speed_profile``):

- ``constant``: ``speed_mps`` throughout;
- ``harmonic``: ``v(t) = speed_mps + amplitude_mps sin(2 pi t / period_s + phase_rad)``
  (``amplitude_mps <= speed_mps``: it never reverses);
- ``piecewise``: from ``speed_mps``, the accelerations of ``accel_profile`` (a list of
  ``{t_s, accel_mps2}``, each from its time until the next), stopping rather than reversing;
- ``braking``: ``speed_mps`` until ``brake_t_s``, then ``brake_decel_mps2`` to a stop.

A lane change (``lane_change_s > 0``) moves the car from ``lateral_offset_m`` to
``lane_change_to_m`` from ``lane_change_t_s`` on, along a half-cosine in time (zero lateral
speed at both ends), heading along its velocity. Every pose is a closed-form function of
time, so the plant, the sensors and the log agree at any instant.

In MuJoCo every car is a copy of ``models/traffic_car.xml`` attached to the world as a mocap
body ``car_<name>/`` (:func:`attach_traffic`); the plant sets the mocap poses after every
physics step (:meth:`Traffic.place`). The cars' body boxes and the ego's body box
(``chassis_shell``) collide with each other only (contact bit :data:`CAR_CONTACT_BIT`; the
ground and the tyres use bit 1), so a contact between the ego and a car is a collision,
which :meth:`Traffic.collision` finds among MuJoCo's contacts.
"""

from __future__ import annotations

import bisect
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from cosim.core.config_fields import from_dict, items, setting
from cosim.core.exceptions import ConfigError
from cosim.core.initial_state import InitialState
from cosim.core.traffic_records import CarPose
from cosim.core.yaml_io import shown

if TYPE_CHECKING:
    from dm_control import mjcf

SPEED_PROFILES = ("constant", "harmonic", "piecewise", "braking")
"""Values of ``traffic.<name>.speed_profile``."""

CAR_CONTACT_BIT = 2
"""``contype``/``conaffinity`` bit of the car bodies: they collide with each other only."""

CAR_PREFIX = "car_"
"""A traffic car ``lead`` is the MuJoCo body ``car_lead/``."""

EGO_BODY_GEOM = "chassis_shell"
"""The ego car's body box, made to collide with traffic when there is traffic."""

TRAFFIC_BODY_GEOM = "shell"
"""The body box of ``models/traffic_car.xml``."""

PARKED_POS_M = (0.0, 0.0, -1000.0)
"""Where a car's body sits in the model, below the ground (it does not collide with it),
until the plant places it on its lane: the ego settles at the origin without traffic."""

_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


@dataclass(frozen=True)
class AccelSegment:
    """From ``t_s`` on (until the next segment), accelerate at ``accel_mps2``."""

    t_s: float = setting(0.0, low=0.0, high=1e5)
    accel_mps2: float = setting(0.0, low=-20.0, high=20.0)


@dataclass(frozen=True)
class TrafficCarConfig:
    """One traffic car: where it starts, how fast it drives, whether it changes lane."""

    gap_m: float = setting(50.0, low=-1e4, high=1e5,
                           doc="start of its centre ahead of the ego's initial CoG [m]")
    lateral_offset_m: float = setting(0.0, low=-100.0, high=100.0,
                                      doc="its line, left of the ego's initial heading [m]")
    speed_profile: str = setting("constant", choices=SPEED_PROFILES)
    speed_mps: float = setting(20.0, low=0.0, high=80.0,
                               doc="constant speed; harmonic: mean; piecewise, braking: start")
    amplitude_mps: float = setting(0.0, low=0.0, high=80.0, doc="harmonic: speed amplitude")
    period_s: float = setting(20.0, low=0.1, high=1e4, doc="harmonic: period")
    phase_rad: float = setting(0.0, low=-6.2832, high=6.2832, doc="harmonic: phase at t = 0")
    accel_profile: tuple[AccelSegment, ...] = items(AccelSegment)
    brake_t_s: float = setting(0.0, low=0.0, high=1e5, doc="braking: when braking starts")
    brake_decel_mps2: float = setting(3.0, low=0.0, high=20.0,
                                      doc="braking: deceleration (positive) [m/s^2]")
    lane_change_t_s: float = setting(0.0, low=0.0, high=1e5, doc="start of its lane change")
    lane_change_s: float = setting(0.0, low=0.0, high=100.0,
                                   doc="duration of its lane change (0: none)")
    lane_change_to_m: float = setting(0.0, low=-100.0, high=100.0,
                                      doc="lateral offset after the lane change [m]")

    def __post_init__(self) -> None:
        if self.speed_profile == "harmonic" and self.amplitude_mps > self.speed_mps:
            raise ConfigError(
                f"amplitude_mps = {self.amplitude_mps:g}: expected at most speed_mps = "
                f"{self.speed_mps:g} (the car would reverse)")
        times = [s.t_s for s in self.accel_profile]
        if any(b <= a for a, b in zip(times, times[1:], strict=False)):
            raise ConfigError(f"accel_profile times {times}: expected strictly increasing")


def traffic_cars(section: dict[str, Any]) -> tuple[tuple[str, TrafficCarConfig], ...]:
    """The ``traffic:`` section (car name -> settings) as validated configs, by name."""
    cars = []
    for name, data in section.items():
        if not isinstance(name, str) or not _NAME.match(name):
            raise ConfigError(f"traffic.{shown(name)}: expected a car name of lower-case "
                              "letters, digits and _ (starting with a letter)")
        if not isinstance(data, dict):  # null would silently be a car of defaults
            value = "null" if data is None else shown(data)
            raise ConfigError(f"traffic.{name} = {value}: expected a mapping of the car's "
                              f"settings (e.g. traffic.{name}.gap_m; `cosim config keys "
                              "traffic.NAME`), or traffic={} for no traffic")
        cars.append((name, from_dict(TrafficCarConfig, data, f"traffic.{name}")))
    return tuple(cars)


class _Longitudinal:
    """Distance and speed along the car's line as closed-form functions of time."""

    def __init__(self, config: TrafficCarConfig) -> None:
        self.config = config
        segments: list[tuple[float, float]] = []
        if config.speed_profile == "piecewise":
            segments = [(s.t_s, s.accel_mps2) for s in config.accel_profile]
        elif config.speed_profile == "braking":
            segments = [(config.brake_t_s, -config.brake_decel_mps2)]
        # Knots (t, s, v, a): the state at the start of each constant-acceleration piece.
        knots = [(0.0, 0.0, config.speed_mps, 0.0)]
        for t_start, accel in segments:
            t0, s0, v0, a0 = knots[-1]
            if t_start <= t0:
                knots[-1] = (t0, s0, v0, accel)
            else:
                knots.append((t_start, *_advance(s0, v0, a0, t_start - t0), accel))
        self._knots = knots
        self._times = [k[0] for k in knots]

    def at(self, t_s: float) -> tuple[float, float, float]:
        """(distance from the start, speed, acceleration) at ``t_s``."""
        c = self.config
        if c.speed_profile == "harmonic":
            w = 2.0 * math.pi / c.period_s
            speed = c.speed_mps + c.amplitude_mps * math.sin(w * t_s + c.phase_rad)
            distance = c.speed_mps * t_s + c.amplitude_mps / w * (
                math.cos(c.phase_rad) - math.cos(w * t_s + c.phase_rad))
            return distance, speed, c.amplitude_mps * w * math.cos(w * t_s + c.phase_rad)
        index = max(bisect.bisect_right(self._times, t_s) - 1, 0)
        t0, s0, v0, a0 = self._knots[index]
        distance, speed = _advance(s0, v0, a0, t_s - t0)
        return distance, speed, (a0 if speed > 0.0 or a0 > 0.0 else 0.0)


def _advance(s0: float, v0: float, a: float, dt: float) -> tuple[float, float]:
    """Distance and speed after ``dt`` at constant acceleration ``a``, stopping at v = 0."""
    if a < 0.0 and v0 + a * dt <= 0.0:
        return s0 + v0 * v0 / (-2.0 * a), 0.0
    return s0 + v0 * dt + 0.5 * a * dt * dt, v0 + a * dt


@dataclass(frozen=True)
class _Lane:
    """The line the car drives along: the ego's initial heading through its start."""

    x0_m: float
    y0_m: float
    yaw_rad: float


class TrafficCar:
    """One car's pose at any time (module docstring)."""

    def __init__(self, name: str, config: TrafficCarConfig, lane: _Lane,
                 length_m: float, width_m: float) -> None:
        self.name = name
        self.config = config
        self._lane = lane
        self._longitudinal = _Longitudinal(config)
        self._lane_direction = (math.cos(lane.yaw_rad), math.sin(lane.yaw_rad))
        self.length_m = length_m
        self.width_m = width_m

    def lateral_offset(self, t_s: float) -> tuple[float, float]:
        """(offset left of the ego's initial heading line [m], its rate [m/s])."""
        c = self.config
        if c.lane_change_s <= 0.0 or t_s <= c.lane_change_t_s:
            return c.lateral_offset_m, 0.0
        u = (t_s - c.lane_change_t_s) / c.lane_change_s
        if u >= 1.0:
            return c.lane_change_to_m, 0.0
        span = c.lane_change_to_m - c.lateral_offset_m
        return (c.lateral_offset_m + span * 0.5 * (1.0 - math.cos(math.pi * u)),
                span * 0.5 * math.pi / c.lane_change_s * math.sin(math.pi * u))

    def _placed(self, t_s: float) -> tuple[float, float, float, float, float, float]:
        """``(x_m, y_m, yaw_rad, speed along the lane, lateral rate, accel)`` at ``t_s``."""
        distance, speed, accel = self._longitudinal.at(t_s)
        offset, offset_rate = self.lateral_offset(t_s)
        lane = self._lane
        along = self.config.gap_m + distance
        cos_yaw, sin_yaw = self._lane_direction
        drift = math.atan2(offset_rate, speed) if speed > 0.0 else 0.0
        return (lane.x0_m + along * cos_yaw - offset * sin_yaw,
                lane.y0_m + along * sin_yaw + offset * cos_yaw,
                lane.yaw_rad + drift, speed, offset_rate, accel)

    def pose(self, t_s: float) -> CarPose:
        x_m, y_m, yaw_rad, speed, offset_rate, accel = self._placed(t_s)
        return CarPose(name=self.name, t_s=t_s, x_m=x_m, y_m=y_m, yaw_rad=yaw_rad,
                       speed_mps=math.hypot(speed, offset_rate), accel_mps2=accel,
                       length_m=self.length_m, width_m=self.width_m)

    def mocap_row(self, t_s: float) -> tuple[float, ...]:
        """The car's mocap position and quaternion at ``t_s`` as :meth:`pose` places it,
        without building the pose (the physics sets it after every step)."""
        x_m, y_m, yaw_rad, *_ = self._placed(t_s)
        return _mocap_row(x_m, y_m, yaw_rad)


class Traffic:
    """The scene's traffic cars, their MuJoCo bodies and the ego's contacts with them."""

    def __init__(self, cars: tuple[tuple[str, TrafficCarConfig], ...],
                 initial: InitialState) -> None:
        self.configs = cars
        self._lane = _Lane(initial.x_m, initial.y_m, initial.yaw_rad)
        self.cars: tuple[TrafficCar, ...] = ()
        self._mocap: tuple[int, ...] = ()
        self._geoms: dict[int, str] = {}
        self._ego_geom = -1
        self.ego_front_m = float("nan")
        """Distance from the ego's CoG forward to its front bumper [m] (from the model)."""

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.configs)

    def bind(self, model: mujoco.MjModel) -> None:
        """Look up each car's mocap slot and body box, and the ego's, by name."""
        body, geom = mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_GEOM
        cars, mocap, geoms = [], [], {}
        for name, config in self.configs:
            body_id = mujoco.mj_name2id(model, body, f"{CAR_PREFIX}{name}/")
            geom_id = mujoco.mj_name2id(model, geom, f"{CAR_PREFIX}{name}/{TRAFFIC_BODY_GEOM}")
            if body_id < 0 or geom_id < 0 or model.body_mocapid[body_id] < 0:
                raise ValueError(f"the model has no mocap traffic car {CAR_PREFIX}{name}/")
            mocap.append(int(model.body_mocapid[body_id]))
            geoms[geom_id] = name
            half_length, half_width, _ = (float(v) for v in model.geom_size[geom_id])
            cars.append(TrafficCar(name, config, self._lane, 2.0 * half_length,
                                   2.0 * half_width))
        self.cars, self._mocap, self._geoms = tuple(cars), tuple(mocap), geoms
        self._ego_geom = mujoco.mj_name2id(model, geom, EGO_BODY_GEOM)
        self.ego_front_m = float(model.geom_pos[self._ego_geom, 0]
                                 + model.geom_size[self._ego_geom, 0])

    def lane_coordinates(self, x_m: float, y_m: float) -> tuple[float, float]:
        """(distance along the lane line from the ego's start, offset to its left) of a
        world point: the frame the cars' scripts are written in."""
        lane = self._lane
        dx, dy = x_m - lane.x0_m, y_m - lane.y0_m
        cos_yaw, sin_yaw = math.cos(lane.yaw_rad), math.sin(lane.yaw_rad)
        return dx * cos_yaw + dy * sin_yaw, -dx * sin_yaw + dy * cos_yaw

    @property
    def lane_yaw_rad(self) -> float:
        return self._lane.yaw_rad

    def poses(self, t_s: float) -> tuple[CarPose, ...]:
        return tuple(car.pose(t_s) for car in self.cars)

    def place(self, data: mujoco.MjData, t_s: float) -> None:
        """Set every car's mocap pose for time ``t_s``."""
        for car, slot in zip(self.cars, self._mocap, strict=True):
            row = car.mocap_row(t_s)
            data.mocap_pos[slot] = row[:3]
            data.mocap_quat[slot] = row[3:]

    @property
    def mocap_slots(self) -> tuple[int, ...]:
        """Each car's mocap slot (after :meth:`bind`), in :attr:`cars` order."""
        return tuple(self._mocap)

    def poses_after_steps(self, t_s: float, dt_s: float, n: int) -> np.ndarray:
        """``(n, cars, 7)``: each car's mocap position and quaternion after each of ``n``
        physics steps from time ``t_s`` (the times MuJoCo's clock reaches, ``t += dt``
        each step), as :meth:`place` sets them."""
        rows: list[tuple[float, ...]] = []
        for _ in range(n):
            t_s = t_s + dt_s
            rows.extend(car.mocap_row(t_s) for car in self.cars)
        return np.array(rows, dtype=float).reshape(n, len(self.cars), 7)

    def collision(self, data: mujoco.MjData) -> str:
        """The name of a car the ego's body touches in the last step's contacts, else ''."""
        if not data.ncon:
            return ""
        ego, geoms = self._ego_geom, self._geoms
        for geom1, geom2 in data.contact.geom.tolist():
            if geom1 == ego and geom2 in geoms:
                return geoms[geom2]
            if geom2 == ego and geom1 in geoms:
                return geoms[geom1]
        return ""


def _mocap_row(x_m: float, y_m: float, yaw_rad: float) -> tuple[float, ...]:
    """The mocap position (on the ground) and quaternion (a yaw) of a car at a pose."""
    half_yaw = 0.5 * yaw_rad
    return (x_m, y_m, 0.0, math.cos(half_yaw), 0.0, 0.0, math.sin(half_yaw))


def attach_traffic(root: mjcf.RootElement, names: tuple[str, ...],
                   load_car: Callable[[], mjcf.RootElement]) -> None:
    """Attach a car from ``load_car()`` (``models/traffic_car.xml``) per name as a mocap body
    ``car_<name>/`` whose body box collides with the ego's body box only."""
    if not names:
        return
    ego_shell = root.find("geom", EGO_BODY_GEOM)
    ego_shell.contype = CAR_CONTACT_BIT
    ego_shell.conaffinity = CAR_CONTACT_BIT
    for name in names:
        car = load_car()
        car.model = f"{CAR_PREFIX}{name}"
        shell = car.find("geom", TRAFFIC_BODY_GEOM)
        shell.contype = CAR_CONTACT_BIT
        shell.conaffinity = CAR_CONTACT_BIT
        frame = root.attach(car)
        frame.mocap = True
        frame.pos = PARKED_POS_M  # out of the way while the ego settles (MujocoPlant)
