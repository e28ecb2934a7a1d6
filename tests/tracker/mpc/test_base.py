"""The MPC skeleton (:mod:`tracker.mpc.base`) behaves the same in every MPC tracker.

Each tracker only specialises the formulation; what happens around the solve (a lost
estimate, a numerical error, a programming error, the safe stop's speed) is one code path,
checked here on all four MPCs.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cosim.core.config_fields import from_dict
from cosim.core.records import Estimate
from tests.tracker.dynamic_closed_loop import ESTIMATE_NAMES, Car, estimate_of
from tracker.config import TrackerConfig
from tracker.mpc.base import MpcTracker
from tracker.paths.double_lane_change import double_lane_change
from tracker.paths.reference_path import ReferencePath
from tracker.registry import make_tracker

MPCS = ("dynamic-nmpc", "kinematic-nmpc", "ltv-mpc", "dynamic-mpc")
LANE_CHANGE = double_lane_change(20.0, 1.5)
NAN = Estimate(0.0, ESTIMATE_NAMES, np.full(len(ESTIMATE_NAMES), np.nan),
               np.eye(len(ESTIMATE_NAMES)))


def _tracker(name: str) -> tuple[MpcTracker, TrackerConfig]:
    config = from_dict(TrackerConfig, {"name": name}, "tracker")
    tracker = make_tracker(config)
    assert isinstance(tracker, MpcTracker)
    return tracker, config


@pytest.mark.parametrize("name", MPCS)
def test_a_lost_estimate_ends_in_a_braking_safe_stop(name: str) -> None:
    """After a good step, an estimate that stays NaN: the last plan is replayed for
    fallback_time_s, then the safe stop brakes from the last plan's speed (the nonlinear
    MPC's stop used to brake from the NaN estimate's speed: it coasted)."""
    tracker, config = _tracker(name)
    _, good = tracker.step(0.0, estimate_of(0.0, Car(0.0, 0.0, 0.0, 15.0)), LANE_CHANGE)
    assert good.success
    steps = [tracker.step(0.05 * i, dataclasses.replace(NAN, t_s=0.05 * i), LANE_CHANGE)
             for i in range(1, 16)]
    stopping = [(c, p) for c, p in steps if p.status.startswith("safe_stop")]
    assert stopping and all(p.fallback and not p.success for _, p in steps)
    assert all(c.accel_mps2 == config.safe_stop_accel_mps2 for c, _ in stopping)
    assert all(np.isfinite([c.accel_mps2, c.steer_rad]).all() for c, _ in steps)


@pytest.mark.parametrize("name", MPCS)
def test_without_any_speed_the_safe_stop_brakes_from_the_top_speed(name: str) -> None:
    tracker, config = _tracker(name)
    steps = [tracker.step(0.05 * i, dataclasses.replace(NAN, t_s=0.05 * i), LANE_CHANGE)
             for i in range(16)]
    command, plan = steps[-1]
    assert plan.status == "safe_stop (non_finite_estimate)"
    assert command.accel_mps2 == config.safe_stop_accel_mps2


class _RaisingPath(ReferencePath):
    """A path whose projection raises ``error``, standing in for any error in a step."""

    error: Exception = ValueError("singular")

    def project(self, x_m: float, y_m: float, *args: object):  # type: ignore[override]
        raise self.error


def _raising(error: Exception) -> ReferencePath:
    path = _RaisingPath(np.linspace(0.0, 100.0, 101), np.zeros(101), 20.0)
    path.error = error
    return path


@pytest.mark.parametrize("name", MPCS)
@pytest.mark.parametrize("error", [RuntimeError("casadi"), ValueError("singular"),
                                   ZeroDivisionError("division")])
def test_a_numerical_error_inside_a_step_is_a_fallback(name: str, error: Exception) -> None:
    tracker, _ = _tracker(name)
    command, plan = tracker.step(0.0, estimate_of(0.0, Car(0.0, 0.0, 0.0, 15.0)),
                                 _raising(error))
    assert plan.fallback and not plan.success
    assert plan.status == f"fallback (error: {type(error).__name__}: {error})"
    assert (command.accel_mps2, command.steer_rad) == (0.0, 0.0)


@pytest.mark.parametrize("name", MPCS)
def test_a_programming_error_is_not_hidden(name: str) -> None:
    tracker, _ = _tracker(name)
    with pytest.raises(TypeError, match="bug"):
        tracker.step(0.0, estimate_of(0.0, Car(0.0, 0.0, 0.0, 15.0)),
                     _raising(TypeError("bug")))
