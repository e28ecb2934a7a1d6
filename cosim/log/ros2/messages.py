"""cosim's logged messages as standard ROS 2 messages: the mapping of the export.

Frames follow REP 103 and REP 105 with the names of the log's own ``/tf``: ``world`` is the
fixed ENU frame (x east, y north, z up; the log's world frame), ``base_link`` the car at its
centre of gravity (ISO 8855, which is REP 103's body convention: x forward, y left, z up).
Every ``header.stamp`` is the source message's log time: ``sim.epoch`` plus sim time
(:mod:`cosim.log.ros2.bag`).

Topics (ROS 2 topic: type, from the log's topic):

- ``/vehicle/truth``: ``nav_msgs/Odometry`` from ``/vehicle/truth``: the true pose (x, y, z,
  roll, pitch, yaw) in ``world``, the body velocities (vx, vy, yaw rate) in ``base_link``;
  covariances zero (exact); the truth logs no vertical, roll or pitch rates: 0;
- ``/vehicle/estimate``: ``nav_msgs/Odometry`` from ``/vehicle/estimate``: the filter's mean
  and covariance (below);
- ``/tf``: ``tf2_msgs/TFMessage`` from ``/vehicle/truth``: ``world`` -> ``base_link``;
- ``/sensors/imu``: ``sensor_msgs/Imu`` from ``/sensors/imu`` (yaw rate, ax, ay);
- ``/sensors/gnss``: ``sensor_msgs/NavSatFix`` from ``/sensors/gnss`` and the log's
  ``geo:`` origin, by the log's own conversion (:func:`cosim.log.foxglove.location_fix`, so
  the coordinates equal the log's ``/gnss/fix``);
- ``/control/command``: ``ackermann_msgs/AckermannDriveStamped`` from ``/control/command``
  (the command as applied): ``steering_angle`` = ``steer_rad``, ``acceleration`` =
  ``accel_mps2``, signed (ackermann_msgs reads an acceleration as a magnitude towards
  ``speed``; cosim commands an acceleration and no speed, so ``speed`` is NaN, "not
  commanded", rather than a number a driver would follow), ``steering_angle_velocity`` and
  ``jerk`` 0 ("no limit" in ackermann_msgs);
- ``/reference/path``: ``nav_msgs/Path`` from ``/reference/path``: the reference, 1 m apart,
  once at the start.

Covariances. ``nav_msgs/Odometry`` holds a 6x6 pose covariance over (x, y, z, rotation about
x, y, z) and a 6x6 twist covariance over (vx, vy, vz, wx, wy, wz), row-major. The estimate's
entries are the filter's covariance between the matching states, by name: pose
(``x_m``, ``y_m``, -, ``roll_rad``, -, ``yaw_rad``), twist (``vx_mps``, ``vy_mps``, -,
``roll_rate_radps``, -, ``yaw_rate_radps``); a quantity the estimator has no state for gets
the variance :data:`UNKNOWN_VARIANCE` and no correlation (ROS has no "unknown" marker for
odometry; a huge variance is what fusion nodes read as "ignore"), and the covariance between
pose and twist is left out (the message has no place for it). ``sensor_msgs/Imu`` has no
orientation (``orientation_covariance[0] = -1``, the message's convention); the components
cosim's planar IMU does not measure (roll and pitch rates, vertical acceleration) are 0
with :data:`UNKNOWN_VARIANCE`; the measured ones carry the sensor's noise variance from the
log. ``NavSatFix`` carries the receiver's variance (``COVARIANCE_TYPE_DIAGONAL_KNOWN``); a
non-finite fix (a fault) is ``STATUS_NO_FIX`` with NaN coordinates.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from rosbags.typesys.store import Typestore

from cosim.core.exceptions import CosimError
from cosim.log.foxglove import (
    CAR_FRAME,
    WORLD_FRAME,
    GeoOrigin,
    location_fix,
    quaternion_from_euler,
)
from cosim.log.ros2 import types as ros

UNKNOWN_VARIANCE = 1e6
"""The variance of a quantity the source does not have (SI units squared)."""
POSE_AXES = ("x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad")
"""The estimate's state for each row of an odometry pose covariance (by name)."""
TWIST_AXES = ("vx_mps", "vy_mps", "vz_mps", "roll_rate_radps", "pitch_rate_radps",
              "yaw_rate_radps")
"""The estimate's state for each row of an odometry twist covariance (by name)."""
IMU_ANGULAR = (None, None, "yaw_rate_radps")
IMU_LINEAR = ("ax_mps2", "ay_mps2", None)
NAV_SAT_STATUS_FIX, NAV_SAT_STATUS_NO_FIX, NAV_SAT_SERVICE_GPS = 0, -1, 1
COVARIANCE_TYPE_DIAGONAL_KNOWN = 2


class RosMessages:
    """Builds the ROS 2 messages of an export (module docstring) with ``store``'s types."""

    def __init__(self, store: Typestore, origin: GeoOrigin) -> None:
        self.types = store.types
        self.origin = origin

    def _header(self, stamp_ns: int, frame: str) -> Any:
        time = self.types["builtin_interfaces/msg/Time"](
            sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
        return self.types["std_msgs/msg/Header"](stamp=time, frame_id=frame)

    def _vector(self, x: float, y: float, z: float) -> Any:
        return self.types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)

    def _quaternion(self, roll: float, pitch: float, yaw: float) -> Any:
        return self.types["geometry_msgs/msg/Quaternion"](
            **quaternion_from_euler(roll, pitch, yaw))

    def _pose(self, x: float, y: float, z: float, roll: float, pitch: float,
              yaw: float) -> Any:
        point = self.types["geometry_msgs/msg/Point"](x=x, y=y, z=z)
        return self.types["geometry_msgs/msg/Pose"](
            position=point, orientation=self._quaternion(roll, pitch, yaw))

    def _odometry(self, stamp_ns: int, pose: Any, pose_covariance: np.ndarray,
                  linear: Any, angular: Any, twist_covariance: np.ndarray) -> Any:
        t = self.types
        return t[ros.ODOMETRY](
            header=self._header(stamp_ns, WORLD_FRAME), child_frame_id=CAR_FRAME,
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose,
                                                            covariance=pose_covariance),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](linear=linear, angular=angular),
                covariance=twist_covariance))

    def truth_odometry(self, stamp_ns: int, truth: dict[str, Any]) -> Any:
        """``/vehicle/truth`` as ``nav_msgs/Odometry`` (exact: zero covariances)."""
        v = truth_numbers(truth)
        pose = self._pose(v["x_m"], v["y_m"], v["z_m"], v["roll_rad"], v["pitch_rad"],
                          v["yaw_rad"])
        return self._odometry(stamp_ns, pose, np.zeros(36),
                              self._vector(v["vx_mps"], v["vy_mps"], 0.0),
                              self._vector(0.0, 0.0, v["yaw_rate_radps"]), np.zeros(36))

    def estimate_odometry(self, stamp_ns: int, estimate: dict[str, Any]) -> Any:
        """``/vehicle/estimate`` as ``nav_msgs/Odometry`` with its covariance (docstring)."""
        names = tuple(estimate["state_names"])
        covariance = _matrix(estimate["covariance"], len(names))
        mean = _numbers({name: estimate[name] for name in names})

        def value(name: str) -> float:
            return mean.get(name, 0.0)

        pose = self._pose(value("x_m"), value("y_m"), 0.0, value("roll_rad"), 0.0,
                          value("yaw_rad"))
        return self._odometry(
            stamp_ns, pose, block_covariance(covariance, names, POSE_AXES),
            self._vector(value("vx_mps"), value("vy_mps"), 0.0),
            self._vector(value("roll_rate_radps"), 0.0, value("yaw_rate_radps")),
            block_covariance(covariance, names, TWIST_AXES))

    def transforms(self, stamp_ns: int, truth: dict[str, Any]) -> Any:
        """``/tf``: ``world`` -> ``base_link`` from the truth."""
        t, v = self.types, truth_numbers(truth)
        transform = t["geometry_msgs/msg/Transform"](
            translation=self._vector(v["x_m"], v["y_m"], v["z_m"]),
            rotation=self._quaternion(v["roll_rad"], v["pitch_rad"], v["yaw_rad"]))
        stamped = t["geometry_msgs/msg/TransformStamped"](
            header=self._header(stamp_ns, WORLD_FRAME), child_frame_id=CAR_FRAME,
            transform=transform)
        return t[ros.TF_MESSAGE](transforms=[stamped])

    def imu(self, stamp_ns: int, measurement: dict[str, Any]) -> Any:
        """``/sensors/imu`` as ``sensor_msgs/Imu`` (docstring)."""
        variances, v = measurement_variances(measurement), _numbers(measurement)

        def vector(axes: tuple[str | None, ...]) -> tuple[Any, np.ndarray]:
            values = [v[a] if a is not None else 0.0 for a in axes]
            diagonal = [variances[a] if a is not None else UNKNOWN_VARIANCE for a in axes]
            return self._vector(*values), np.diag(diagonal).ravel()

        angular, angular_covariance = vector(IMU_ANGULAR)
        linear, linear_covariance = vector(IMU_LINEAR)
        no_orientation = np.zeros(9)
        no_orientation[0] = -1.0
        return self.types[ros.IMU](
            header=self._header(stamp_ns, CAR_FRAME),
            orientation=self._quaternion(0.0, 0.0, 0.0),
            orientation_covariance=no_orientation, angular_velocity=angular,
            angular_velocity_covariance=angular_covariance, linear_acceleration=linear,
            linear_acceleration_covariance=linear_covariance)

    def nav_sat_fix(self, stamp_ns: int, measurement: dict[str, Any]) -> Any:
        """``/sensors/gnss`` as ``sensor_msgs/NavSatFix`` (docstring)."""
        v = _numbers(measurement)
        finite = math.isfinite(v["x_m"]) and math.isfinite(v["y_m"])
        sigma_m = math.sqrt(measurement_variances(measurement)["x_m"])
        fix = location_fix(v["x_m"], v["y_m"], 0.0, sigma_m, self.origin)
        status = self.types["sensor_msgs/msg/NavSatStatus"](
            status=NAV_SAT_STATUS_FIX if finite else NAV_SAT_STATUS_NO_FIX,
            service=NAV_SAT_SERVICE_GPS)
        return self.types[ros.NAV_SAT_FIX](
            header=self._header(stamp_ns, CAR_FRAME), status=status,
            latitude=fix["latitude"], longitude=fix["longitude"], altitude=fix["altitude"],
            position_covariance=np.asarray(fix["position_covariance"], dtype=float),
            position_covariance_type=COVARIANCE_TYPE_DIAGONAL_KNOWN)

    def ackermann(self, stamp_ns: int, command: dict[str, Any]) -> Any:
        """``/control/command`` as ``ackermann_msgs/AckermannDriveStamped`` (docstring)."""
        v = _numbers(command)
        drive = self.types[ros.ACKERMANN_DRIVE](
            steering_angle=v["steer_rad"], steering_angle_velocity=0.0, speed=math.nan,
            acceleration=v["accel_mps2"], jerk=0.0)
        return self.types[ros.ACKERMANN_DRIVE_STAMPED](
            header=self._header(stamp_ns, CAR_FRAME), drive=drive)

    def path(self, stamp_ns: int, reference: dict[str, Any]) -> Any:
        """``/reference/path`` as ``nav_msgs/Path`` in ``world``."""
        header = self._header(stamp_ns, WORLD_FRAME)
        poses = [self.types[ros.POSE_STAMPED](header=header,
                                              pose=self._pose(x, y, 0.0, 0.0, 0.0, yaw))
                 for x, y, yaw in zip(reference["x_m"], reference["y_m"],
                                      reference["yaw_rad"], strict=True)]
        return self.types[ros.PATH](header=header, poses=poses)


TRUTH_REQUIRED = ("x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "yaw_rate_radps")
"""Truth fields every cosim log has had: without them the message is no cosim truth."""

TRUTH_PLANAR = ("z_m", "roll_rad", "pitch_rad")
"""Truth fields older logs lack (they logged the planar state only): exported as 0."""


def truth_numbers(truth: dict[str, Any]) -> dict[str, float]:
    """A ``/vehicle/truth`` message's numbers; a field older logs lack (:data:`TRUTH_PLANAR`)
    is 0, a field every log has is required (a CosimError naming it)."""
    v = _numbers(truth)
    missing = [name for name in TRUTH_REQUIRED if name not in v]
    if missing:
        raise CosimError(f"/vehicle/truth without {', '.join(missing)}: expected the truth "
                         "of a cosim log (x_m, y_m, yaw_rad, vx_mps, vy_mps, yaw_rate_radps)")
    for name in TRUTH_PLANAR:
        v.setdefault(name, 0.0)
    return v


def planar_fields_missing(truth: dict[str, Any]) -> list[str]:
    """The fields of :data:`TRUTH_PLANAR` a truth message lacks (an older log)."""
    return [name for name in TRUTH_PLANAR if name not in truth]


def _numbers(message: dict[str, Any]) -> dict[str, float]:
    """The message's numbers as floats; the log writes a non-finite value as null: NaN."""
    return {k: math.nan if v is None else float(v) for k, v in message.items()
            if v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))}


def _matrix(values: list[float | None], size: int) -> np.ndarray:
    """A square matrix from its row-major values; the log's nulls (non-finite) as NaN."""
    if None in values:
        values = [math.nan if v is None else v for v in values]
    return np.array(values, dtype=float).reshape(size, size)


def block_covariance(covariance: np.ndarray, names: tuple[str, ...],
                     axes: tuple[str, ...]) -> np.ndarray:
    """The 6x6 covariance over ``axes`` (row-major, 36 values) from the estimate's
    covariance over ``names``; an axis without a state gets :data:`UNKNOWN_VARIANCE`."""
    rows = np.array([names.index(a) if a in names else -1 for a in axes])
    known = rows >= 0
    out = np.zeros((len(axes), len(axes)))
    out[np.ix_(known, known)] = covariance[np.ix_(rows[known], rows[known])]
    out[~known, ~known] = UNKNOWN_VARIANCE
    return out.ravel()


def measurement_variances(measurement: dict[str, Any]) -> dict[str, float]:
    """Each measured quantity's noise variance: the logged ``sigma`` list, in the order of
    the measurement's values."""
    names = [k for k in measurement if k not in ("t_s", "sensor", "sigma")]
    return {name: float(sigma) ** 2
            for name, sigma in zip(names, measurement["sigma"], strict=True)}
