"""The ROS 2 message types of an export, from rosbags' typestore.

The standard messages (``nav_msgs``, ``sensor_msgs``, ``geometry_msgs``, ``tf2_msgs``,
``std_msgs``) are rosbags' definitions of ROS 2 Humble, which Iron, Jazzy and Kilted keep
unchanged for these types. ``ackermann_msgs`` (the ROS package of the same name,
``AckermannDrive`` and ``AckermannDriveStamped``) is not part of ROS's core; its two
definitions are registered here, so that the export carries them as its schemas and a
reader needs no ``ackermann_msgs`` to decode the command.
"""

from __future__ import annotations

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

ODOMETRY = "nav_msgs/msg/Odometry"
PATH = "nav_msgs/msg/Path"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
IMU = "sensor_msgs/msg/Imu"
NAV_SAT_FIX = "sensor_msgs/msg/NavSatFix"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
ACKERMANN_DRIVE = "ackermann_msgs/msg/AckermannDrive"
ACKERMANN_DRIVE_STAMPED = "ackermann_msgs/msg/AckermannDriveStamped"

ACKERMANN_DEFINITIONS: dict[str, str] = {
    ACKERMANN_DRIVE: (
        "float32 steering_angle\n"
        "float32 steering_angle_velocity\n"
        "float32 speed\n"
        "float32 acceleration\n"
        "float32 jerk\n"),
    ACKERMANN_DRIVE_STAMPED: (
        "std_msgs/Header header\n"
        "AckermannDrive drive\n"),
}
"""``ackermann_msgs``' definitions (its ``msg/*.msg`` files' fields; units: rad, rad/s,
m/s, m/s^2, m/s^3)."""


def typestore() -> Typestore:
    """ROS 2 Humble's types plus ``ackermann_msgs``."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    for name, text in ACKERMANN_DEFINITIONS.items():
        store.register(get_types_from_msg(text, name))
    return store
