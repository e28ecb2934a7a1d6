"""The room a surprise makes in the covariance (estimation.covariance_room.room_for_surprise):
the least that brings the ungated sensor's NIS back to the gate."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from estimation.covariance_room import room_for_surprise


def _problem(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A random belief of 6 states, a process noise that drives the first 4 (the last two
    are biases it leaves alone), 3 channels that see all six, and their noise."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(6, 6))
    p = a @ a.T + 0.1 * np.eye(6)
    b = rng.normal(size=(4, 4))
    q = np.zeros((6, 6))
    q[:4, :4] = b @ b.T + 0.1 * np.eye(4)
    h = rng.normal(size=(3, 6))
    r = np.diag(rng.uniform(0.1, 1.0, 3))
    return p, q, h, r


def _nis(p: np.ndarray, h: np.ndarray, r: np.ndarray, y: np.ndarray) -> float:
    return float(y @ np.linalg.solve(h @ p @ h.T + r, y))


@pytest.mark.parametrize("scale", [1.3, 3.0, 100.0])
def test_the_room_brings_the_nis_to_the_gate(scale: float) -> None:
    threshold = float(chi2.ppf(0.9999, 3))
    for seed in range(5):
        p, q, h, r = _problem(seed)
        y = np.random.default_rng(100 + seed).normal(size=3)
        y *= np.sqrt(scale * threshold / _nis(p, h, r, y))  # n = scale x the gate
        n = _nis(p, h, r, y)
        room = room_for_surprise(p, q, h, y, n, threshold)
        assert room is not None
        assert _nis(room, h, r, y) == pytest.approx(threshold, rel=1e-9)
        # Only the states the process noise drives get room; the biases keep theirs.
        np.testing.assert_array_equal(room[4:, :], p[4:, :])
        assert np.all(np.linalg.eigvalsh(room - p) > -1e-9)  # it only grows


def test_no_room_inside_the_gate() -> None:
    p, q, h, r = _problem(0)
    y = np.array([0.1, -0.2, 0.05])
    n = _nis(p, h, r, y)
    assert room_for_surprise(p, q, h, y, n, threshold=n) is None
    assert room_for_surprise(p, q, h, y, n, threshold=2.0 * n) is None


def test_a_sample_just_outside_gets_far_less_room_than_a_kick() -> None:
    """A noise sample just past the gate gets a sliver of the room a kick 30 times the gate
    gets; the whole innovation taken as motion (the room of a = 1) would give both about the
    same NIS, below 1."""
    threshold = float(chi2.ppf(0.9999, 3))
    p, q, h, r = _problem(3)
    direction = np.array([1.0, 0.5, -0.3])
    unit = direction / np.sqrt(_nis(p, h, r, direction))
    tail = unit * np.sqrt(1.5 * threshold)
    kick = unit * np.sqrt(30.0 * threshold)
    grown = [np.trace(room_for_surprise(p, q, h, y, _nis(p, h, r, y), threshold) - p)
             for y in (tail, kick)]
    # a = 1 / threshold - 1 / n times |G y|^2, which grows with n: 20 x (1 - 1/30) / (1 - 1/1.5)
    assert grown[1] / grown[0] == pytest.approx(20.0 * (1 - 1 / 30) / (1 - 1 / 1.5), rel=1e-9)
