"""``cosim config show`` prints what a run reads: the left-out keys change nothing."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from cosim.core.config_fields import to_dict
from cosim.simulation.course import build_course
from cosim.simulation.path_config import PATH_KINDS, SPEED_PROFILES, PathConfig, path_keys_read
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from cosim.simulation.used_config import used_config
from tests.simulation.test_run import _payloads

NUMERIC_PATH_KEYS = ("stretch", "length_m", "radius_m", "arc_deg", "approach_m", "spacing_m",
                     "amplitude_m", "lat_accel_max_mps2", "accel_max_mps2",
                     "decel_max_mps2", "grip_share", "tracking_share", "cruise_s", "stop_s")


def _course_signature(path: PathConfig) -> np.ndarray:
    config = load_config("lane-change")
    course = build_course(path, config.initial, config.plant, 30.0, config.tracker)
    reference = course.reference
    s = np.linspace(0.0, 0.95 * reference.length_m, 200)
    samples = reference.sample(s)
    speed = np.concatenate([reference.speed_ref(s, t) for t in (0.0, 5.0, 9.0, 20.0)])
    return np.concatenate([samples["x_m"], samples["y_m"], speed, [reference.length_m]])


@pytest.mark.parametrize("kind", [k for k in PATH_KINDS if k != "track"])
@pytest.mark.parametrize("profile", SPEED_PROFILES)
def test_the_path_keys_left_out_change_nothing(kind: str,
                                                 profile: str) -> None:
    base = PathConfig(kind=kind, speed_profile=profile, cones=6)
    signature = _course_signature(base)
    read = path_keys_read(kind, profile)
    for key in NUMERIC_PATH_KEYS:
        changed = dataclasses.replace(base, **{key: getattr(base, key) * 1.2})
        differs = not np.array_equal(_course_signature(changed), signature)
        if key not in read:
            assert not differs, f"{kind}/{profile}: path.{key} is read but left out"


def test_config_show_leaves_out_what_a_lane_change_does_not_read() -> None:
    full = to_dict(load_config("lane-change"))
    used = used_config(full)
    assert "manoeuvre" in full and "manoeuvre" not in used
    assert "radar" in full["sensors"] and "radar" not in used["sensors"]
    assert "acc" in full["tracker"] and "acc" not in used["tracker"]
    assert "ltv_mpc" in full["tracker"] and "ltv_mpc" not in used["tracker"]
    assert "baseline" in full["tracker"] and "baseline" not in used["tracker"]
    assert "horizon" in used["tracker"] and "weights" in used["tracker"]
    assert set(used["path"]) == {"kind", "speed_mps", "speed_profile", "stretch", "length_m"}
    acc = used_config(to_dict(load_config("acc")))
    assert "radar" in acc["sensors"] and "acc" in acc["tracker"] and acc["traffic"]
    open_loop = used_config(to_dict(load_config("step-steer")))
    assert "manoeuvre" in open_loop


@pytest.mark.parametrize("scenario", ["lane-change", "acc-cut-in"])
@pytest.mark.slow
def test_the_printed_config_runs_the_same_car(scenario: str, tmp_path: Path) -> None:
    config = load_config(scenario, duration_s=1.0)
    pruned = tmp_path / "pruned.yaml"
    pruned.write_text(yaml.safe_dump(used_config(to_dict(config)), sort_keys=False))
    first = run(config, tmp_path / "full.mcap")
    second = run(load_config(str(pruned)), tmp_path / "pruned.mcap")
    assert _payloads(first.log_path)["/vehicle/truth"] == \
        _payloads(second.log_path)["/vehicle/truth"]
