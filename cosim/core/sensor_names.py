"""The names of the sensors: one place for the strings that key a sensor everywhere.

A sensor's name is its section under ``sensors:`` in a scenario, the ``sensor`` of its
:class:`cosim.core.records.Measurement`, its topic ``/sensors/<name>``, its random stream
(``sensors.<name>``), the estimator's measurement model and noise belief for it, and the
suffix of its metrics (``nis_<name>``). Every module that keys by sensor takes the name from
here, so a sensor added or renamed is added or renamed once.
"""

from __future__ import annotations

GNSS = "gnss"
"""GNSS position of the antenna (world x, y)."""
GNSS_VELOCITY = "gnss_velocity"
"""GNSS velocity over the ground from the carriers' Doppler shift (east, north)."""
HEADING = "heading"
"""Dual-antenna GNSS heading (yaw)."""
IMU = "imu"
"""Yaw rate and the two planar accelerations."""
WHEEL_SPEED = "wheel_speed"
"""The four wheels' angular speeds (ABS encoders)."""
STEERING = "steering"
"""The road-wheel steering angle (EPS angle sensor)."""
RADAR = "radar"
"""The ACC's forward range sensor: read by the tracker, never fused by the estimator."""
TRUTH = "truth"
"""The noise-free true state, for the ``truth`` estimator (debugging) only."""

FUSED_SENSORS: tuple[str, ...] = (GNSS, GNSS_VELOCITY, HEADING, IMU, WHEEL_SPEED, STEERING)
"""Every sensor the state estimator can fuse, in the order of their ``sensors:`` sections."""

SENSOR_NAMES: tuple[str, ...] = (*FUSED_SENSORS, RADAR, TRUTH)
"""Every sensor a run can have."""
