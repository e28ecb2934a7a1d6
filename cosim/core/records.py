"""Values that cross component boundaries: truth, commands, measurements, estimates, plans.

Frames and units follow docs/architecture.md: world frame ENU (x east, y north, z up),
vehicle frame ISO 8855 (x forward, y left, z up), yaw counter-clockwise positive, steering
positive to the left, SI units with the unit in every name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def flat_message(record: object) -> dict[str, object]:
    """A flat record (a dataclass whose fields are numbers and strings) as a message: its
    fields in order, as ``dataclasses.asdict`` gives them, without the deep copy of every
    value that makes ``asdict`` some 10 us a record."""
    return dict(vars(record))


WHEEL_NAMES: tuple[str, ...] = ("front_left", "front_right", "rear_left", "rear_right")
"""Order of the four wheels in every per-wheel tuple."""


@dataclass(frozen=True)
class VehicleState:
    """The true state of the plant at ``t_s``.

    Position is the centre of gravity in the world frame; velocities and accelerations are
    those of the centre of gravity expressed in the vehicle frame; ``ax_mps2``/``ay_mps2`` are
    the kinematic accelerations (no gravity), ``steer_rad`` is the road-wheel angle of the
    front axle (mean of the two front wheels).
    """

    t_s: float
    x_m: float
    y_m: float
    z_m: float
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    vx_mps: float
    vy_mps: float
    yaw_rate_radps: float
    ax_mps2: float
    ay_mps2: float
    steer_rad: float
    wheel_speed_radps: tuple[float, float, float, float]

    @property
    def speed_mps(self) -> float:
        """Magnitude of the horizontal velocity of the centre of gravity."""
        return float(np.hypot(self.vx_mps, self.vy_mps))

    def to_message(self) -> dict[str, object]:
        """Plain JSON-ready fields (the `/vehicle/truth` payload)."""
        message = dict(self.__dict__)  # the fields: all plain floats but one tuple
        message["wheel_speed_radps"] = list(self.wheel_speed_radps)
        return message


@dataclass(frozen=True)
class Command:
    """What a tracker asks of the car: longitudinal acceleration and road-wheel angle."""

    t_s: float
    accel_mps2: float
    steer_rad: float

    def to_message(self) -> dict[str, object]:
        return flat_message(self)


@dataclass(frozen=True)
class Measurement:
    """One sample of one sensor: named values and their noise covariance."""

    sensor: str
    t_s: float
    names: tuple[str, ...]
    values: np.ndarray
    covariance: np.ndarray

    def __getitem__(self, name: str) -> float:
        return float(self.values[self.names.index(name)])

    def to_message(self) -> dict[str, object]:
        message: dict[str, object] = {"t_s": self.t_s, "sensor": self.sensor}
        message.update(zip(self.names, _json_floats(self.values), strict=True))
        message["sigma"] = np.sqrt(np.asarray(self.covariance, dtype=float).diagonal()).tolist()
        return message


@dataclass(frozen=True)
class Estimate:
    """An estimator's belief at ``t_s``: mean and covariance over named states.

    Read states by name (``estimate["yaw_rad"]``), never by index.
    """

    t_s: float
    names: tuple[str, ...]
    mean: np.ndarray
    covariance: np.ndarray

    def __getitem__(self, name: str) -> float:
        return float(self.mean[self.names.index(name)])

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def sub_covariance(self, names: tuple[str, ...]) -> np.ndarray:
        """The covariance block of the named states, in the order given."""
        idx = [self.names.index(n) for n in names]
        first = idx[0] if idx else 0
        if idx == list(range(first, first + len(idx))):
            # Neighbours: a slice's copy, laid out as the indexing below lays it out (by
            # columns), so that products with it round alike.
            return self.covariance[first:first + len(idx), first:first + len(idx)].copy("F")
        return self.covariance[idx][:, idx]  # the rows, then their columns (np.ix_'s block)

    def to_message(self) -> dict[str, object]:
        message: dict[str, object] = {"t_s": self.t_s}
        message.update(zip(self.names, np.asarray(self.mean, dtype=float).tolist(),
                           strict=True))
        message["state_names"] = list(self.names)
        # An array: the log's encoder writes it as a JSON list (NaN as null), unconverted.
        message["covariance"] = np.ascontiguousarray(self.covariance, dtype=float).reshape(-1)
        return message


@dataclass(frozen=True)
class Plan:
    """A tracker's plan at ``t_s``: predicted states and inputs over its horizon.

    ``states`` has one row per horizon node (N + 1 rows) and one column per name in
    ``state_names``; ``inputs`` has N rows and the columns ``input_names``.
    """

    t_s: float
    dt_s: float
    state_names: tuple[str, ...]
    states: np.ndarray
    input_names: tuple[str, ...]
    inputs: np.ndarray
    cost: float
    solve_time_s: float
    iterations: int
    status: str
    success: bool
    fallback: bool
    speed_reduced: bool = False
    """The tracker planned below the reference speed because the path ahead cannot be
    held at it (the believed friction; :mod:`tracker.mpc.grip_speed`)."""

    @classmethod
    def of_command(cls, command: Command, status: str = "command") -> Plan:
        """The plan of a tracker that plans nothing: no predicted states, one input row
        (the command itself), no cost, success. What a tracker whose ``step`` returns a
        :class:`Command` alone is logged with."""
        return cls(t_s=command.t_s, dt_s=0.0, state_names=(), states=np.zeros((1, 0)),
                   input_names=("accel_mps2", "steer_rad"),
                   inputs=np.array([[command.accel_mps2, command.steer_rad]], dtype=float),
                   cost=0.0, solve_time_s=0.0, iterations=0, status=status, success=True,
                   fallback=False)

    def column(self, name: str) -> np.ndarray:
        """One predicted state or input over the horizon, by name."""
        if name in self.state_names:
            return self.states[:, self.state_names.index(name)]
        return self.inputs[:, self.input_names.index(name)]

    def to_message(self) -> dict[str, object]:
        message: dict[str, object] = {
            "t_s": self.t_s,
            "dt_s": self.dt_s,
            "cost": _json_float(self.cost),
            "solve_time_s": self.solve_time_s,
            "iterations": self.iterations,
            "status": self.status,
            "success": self.success,
            "fallback": self.fallback,
            "speed_reduced": self.speed_reduced,
        }
        for name in self.state_names + self.input_names:  # arrays, as Estimate's covariance
            message[f"predicted_{name}"] = np.ascontiguousarray(self.column(name), dtype=float)
        return message


def _json_float(value: float) -> float | None:
    """JSON has no NaN: a non-finite value is logged as null."""
    value = float(value)
    return value if math.isfinite(value) else None


def _json_floats(values: np.ndarray) -> list[float | None]:
    """:func:`_json_float` of every entry (one conversion to Python floats, then a pass)."""
    return [v if math.isfinite(v) else None
            for v in np.asarray(values, dtype=float).ravel().tolist()]


@dataclass(frozen=True)
class ActuatorCommand:
    """What the low-level layer asks of the plant's actuators, valid from ``t_s`` on.

    ``drive_torque_nm`` is the total drive torque at the wheels (>= 0), ``brake_torque_nm``
    the total brake torque of all four wheels (>= 0), ``steer_rad`` the road-wheel angle of
    the bicycle model (positive left) that the steering actuator is asked to reach.
    """

    t_s: float
    drive_torque_nm: float
    brake_torque_nm: float
    steer_rad: float

    def __post_init__(self) -> None:
        for name in ("t_s", "drive_torque_nm", "brake_torque_nm", "steer_rad"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ValueError(f"ActuatorCommand.{name} = {value!r}: expected a finite number")
        if self.drive_torque_nm < 0.0:
            raise ValueError(
                f"ActuatorCommand.drive_torque_nm = {self.drive_torque_nm}: expected >= 0"
            )
        if self.brake_torque_nm < 0.0:
            raise ValueError(
                f"ActuatorCommand.brake_torque_nm = {self.brake_torque_nm}: expected >= 0"
            )

    def to_message(self) -> dict[str, object]:
        return flat_message(self)
