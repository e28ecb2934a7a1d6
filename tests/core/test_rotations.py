"""Euler angles and quaternions of the body frame against MuJoCo's own conversion."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from cosim.core.rotations import euler_zyx, quaternion_zyx

ANGLES = [(0.0, 0.0, 0.0), (1.2, -0.03, 0.05), (-2.9, 0.2, -0.1), (3.0, 1.4, -2.5)]


@pytest.mark.parametrize(("yaw", "pitch", "roll"), ANGLES)
def test_the_quaternion_is_mujocos_intrinsic_zyx(yaw: float, pitch: float,
                                                 roll: float) -> None:
    reference = np.empty(4)
    mujoco.mju_euler2Quat(reference, np.array([yaw, pitch, roll]), "zyx")
    assert quaternion_zyx(yaw, pitch, roll) == pytest.approx(tuple(reference), abs=1e-12)


@pytest.mark.parametrize(("yaw", "pitch", "roll"), ANGLES)
def test_euler_angles_invert_the_quaternion(yaw: float, pitch: float, roll: float) -> None:
    assert euler_zyx(*quaternion_zyx(yaw, pitch, roll)) == pytest.approx(
        (roll, pitch, yaw), abs=1e-12)


def test_the_rotation_is_yaw_then_pitch_then_roll() -> None:
    """Against R = Rz(yaw) Ry(pitch) Rx(roll), written out."""
    yaw, pitch, roll = 0.7, -0.1, 0.05
    cz, sz, cy, sy, cx, sx = (math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch),
                              math.cos(roll), math.sin(roll))
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    matrix = np.empty(9)
    mujoco.mju_quat2Mat(matrix, np.array(quaternion_zyx(yaw, pitch, roll)))
    assert np.allclose(matrix.reshape(3, 3), rz @ ry @ rx)
