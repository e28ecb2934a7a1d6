"""Euler angles and unit quaternions of the ISO 8855 body frame (yaw, pitch, roll).

The body's orientation is yaw ``psi`` about z, then pitch ``theta`` about the turned y, then
roll ``phi`` about the twice-turned x (intrinsic z-y'-x'', ISO 8855:2011 sec. 5.2). As a
unit quaternion ``(w, x, y, z)`` (Diebel, "Representing attitude: Euler angles, unit
quaternions, and rotation vectors", Stanford 2006, eq. 290 and 297, the 3-2-1 sequence):

    w = cr cp cy + sr sp sy        x = sr cp cy - cr sp sy
    y = cr sp cy + sr cp sy        z = cr cp sy - sr sp cy

with ``cr = cos(phi/2)``, ``sr = sin(phi/2)`` and so on.
"""

from __future__ import annotations

import math


def quaternion_zyx(yaw_rad: float, pitch_rad: float,
                   roll_rad: float) -> tuple[float, float, float, float]:
    """Unit quaternion ``(w, x, y, z)`` of yaw, then pitch, then roll (module docstring)."""
    cy, sy = math.cos(0.5 * yaw_rad), math.sin(0.5 * yaw_rad)
    cp, sp = math.cos(0.5 * pitch_rad), math.sin(0.5 * pitch_rad)
    cr, sr = math.cos(0.5 * roll_rad), math.sin(0.5 * roll_rad)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def euler_zyx(qw: float, qx: float, qy: float, qz: float) -> tuple[float, float, float]:
    """Roll, pitch, yaw of a unit quaternion ``w x y z`` (the inverse of
    :func:`quaternion_zyx`; pitch within [-pi/2, pi/2])."""
    roll = math.atan2(2.0 * (qw * qx + qy * qz), 1.0 - 2.0 * (qx * qx + qy * qy))
    sin_pitch = 2.0 * (qw * qy - qz * qx)
    pitch = math.asin(min(max(sin_pitch, -1.0), 1.0))
    yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    return roll, pitch, yaw
