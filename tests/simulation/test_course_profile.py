"""A circuit's speed profile within the car and the tracker; where the car starts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosim.simulation.course import profile_limits
from cosim.simulation.runner import scenario_course, start_speed_resolved
from cosim.simulation.scenario_config import load_config

OVAL = "\n".join(["x,y"] + [f"{60 * np.cos(t):.3f},{30 * np.sin(t):.3f}"
                           for t in np.linspace(0.0, 2 * np.pi, 200, endpoint=False)])


def test_the_profile_stays_within_the_trackers_bounds_and_the_believed_grip() -> None:
    config = load_config("track", overrides=["tracker.accel_min_mps2=-2.5",
                                             "tracker.model.tyre_friction=0.8"])
    limits = profile_limits(config.path, config.tracker)
    assert limits.decel_max_mps2 == pytest.approx(0.8 * 2.5)  # tracking_share x bound
    assert limits.lat_accel_max_mps2 == pytest.approx(0.7 * 0.8 * 9.81)  # grip_share x mu g
    reference = scenario_course(config).reference
    s = np.arange(0.0, reference.length_m, 0.5)
    v = reference.speed_ref(s, 0.0)
    # Braking between two samples never asks for more than the limit (v dv/ds = a).
    decel = -np.diff(v**2) / (2.0 * np.diff(s))
    assert decel.max() <= limits.decel_max_mps2 * 1.02
    curvature = np.abs(reference.sample(s)["curvature_1pm"])
    assert np.max(v**2 * curvature) <= limits.lat_accel_max_mps2 * 1.02


def test_a_tight_first_bend_is_entered_at_the_profiles_speed(tmp_path: Path) -> None:
    oval = tmp_path / "oval.csv"
    oval.write_text(OVAL + "\n")  # 120 x 60 m, its first point at the 15 m radius end
    config = load_config("track", overrides=[f"path.file={oval}"])
    resolved = start_speed_resolved(config, scenario_course(config).reference)
    # sqrt(6 m/s^2 x 15 m) = 9.5 m/s where the bend is tightest, not the 22 m/s of a ring.
    assert resolved.initial.speed_mps == pytest.approx(np.sqrt(6.0 * 15.0), rel=0.05)
    fixed = load_config("track", overrides=[f"path.file={oval}",
                                            "initial.speed_from_profile=false",
                                            "initial.speed_mps=22"])
    assert start_speed_resolved(fixed, scenario_course(fixed).reference) is fixed
