"""The FMU tracker against plain Python references of the example FMUs' laws (FMI 2 and 3)."""

from __future__ import annotations

import importlib.util
import math
import tempfile
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

import tracker.fmu.slave as slave_module
from cosim.core.config_fields import from_dict
from cosim.core.exceptions import TrackerFault
from cosim.core.records import Estimate
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from tracker.config import TrackerConfig
from tracker.fmu.signals import InputFeed
from tracker.fmu.tracker import FmuTracker
from tracker.paths.reference_path import ReferencePath

PERIOD_S = 0.05
EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "fmu"
STANLEY_INPUTS = ("cte_m", "heading_err_rad", "speed_mps", "ref_speed_mps", "curvature_1pm",
                  "est_yaw_rate_radps")


def pure_pursuit_law() -> ModuleType:
    """examples/fmu/pure_pursuit_law.py, loaded from its file (an example, not a package)."""
    spec = importlib.util.spec_from_file_location("example_pure_pursuit_law",
                                                  EXAMPLES / "pure_pursuit_law.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def s_bend() -> ReferencePath:
    s = np.linspace(0.0, 300.0, 601)
    return ReferencePath(s, 3.0 * np.sin(s / 40.0), 18.0)


def estimates() -> list[Estimate]:
    """A car weaving beside the path, one estimate per control period."""
    names = ("x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "yaw_rate_radps")
    out = []
    for k in range(4):
        state = np.array([20.0 + 0.9 * k, 0.6 - 0.3 * k, 0.05 * (k - 1), 17.0 + 0.2 * k,
                          0.1, 0.02 * k])
        out.append(Estimate(k * PERIOD_S, names, state, np.eye(len(names))))
    return out


def stanley_reference(cte: float, heading: float, v: float, v_ref: float, kappa: float,
                      r: float, gain: float = 1.5) -> tuple[float, float]:
    """examples/fmu/stanley.c's law with its start values, written out."""
    steer = (-heading - math.atan(gain * cte / (1.0 + v)) + 2.8 * kappa
             - 0.1 * (r - v * kappa))
    return steer, 1.0 * (v_ref - v)


@pytest.mark.parametrize("version", [2, 3])
def test_the_c_fmu_computes_stanleys_law_on_cosims_signals(version: int,
                                                           c_fmus: dict[int, Path]) -> None:
    config = TrackerConfig(name=f"fmu:{c_fmus[version]}")
    fmu = FmuTracker(config, PERIOD_S)
    reference, feed = s_bend(), InputFeed(STANLEY_INPUTS, config.fmu.preview_spacing_m)
    try:
        for k, estimate in enumerate(estimates()):
            command, plan = fmu.step(k * PERIOD_S, estimate, reference)
            steer, accel = stanley_reference(*feed.values(k * PERIOD_S, estimate, reference))
            assert abs(steer) < config.max_steer_rad  # not clipped: the law itself
            assert (command.steer_rad, command.accel_mps2) == pytest.approx((steer, accel),
                                                                            abs=1e-12)
            assert plan.status == "ok" and not plan.fallback
    finally:
        fmu.close()


@pytest.mark.parametrize("version", [2, 3])
def test_the_python_fmu_pursues_cosims_preview_points(version: int,
                                                      python_fmus: dict[int, Path]) -> None:
    law = pure_pursuit_law()
    config = TrackerConfig(name=f"fmu:{python_fmus[version]}")
    fmu = FmuTracker(config, PERIOD_S)
    names = ("speed_mps", *(f"preview_{a}_m[{i}]" for i in range(1, law.PREVIEW_POINTS + 1)
                            for a in "xy"))
    reference, feed = s_bend(), InputFeed(names, config.fmu.preview_spacing_m)
    try:
        for k, estimate in enumerate(estimates()):
            command, _ = fmu.step(k * PERIOD_S, estimate, reference)
            speed, *points = feed.values(k * PERIOD_S, estimate, reference)
            steer = law.steer_rad(points[0::2], points[1::2], speed, 2.8, 1.6, 0.0039, 0.6,
                                  4.0, 40.0)
            assert command.steer_rad == pytest.approx(steer, abs=1e-12)
            assert command.accel_mps2 == pytest.approx(18.0 - speed, abs=1e-12)
    finally:
        fmu.close()


def test_commands_beyond_the_bounds_are_clipped(c_fmus: dict[int, Path]) -> None:
    config = from_dict(TrackerConfig, {"name": f"fmu:{c_fmus[2]}", "accel_max_mps2": 0.5,
                                       "fmu": {"parameters": {"gain_1ps": 1e4}}})
    fmu = FmuTracker(config, PERIOD_S)
    try:
        command, plan = fmu.step(0.0, estimates()[0], s_bend())  # 0.8 m right of the path
    finally:
        fmu.close()
    assert (command.steer_rad, command.accel_mps2) == (config.max_steer_rad, 0.5)
    assert plan.status == "clipped" and plan.success and not plan.fallback


def test_a_step_off_the_control_period_is_a_fault(c_fmus: dict[int, Path]) -> None:
    fmu = FmuTracker(TrackerConfig(name=f"fmu:{c_fmus[3]}"), PERIOD_S)
    try:
        fmu.step(0.0, estimates()[0], s_bend())
        with pytest.raises(TrackerFault, match="expected one step per control period"):
            fmu.step(3 * PERIOD_S, estimates()[1], s_bend())
        fmu.reset()  # a fresh instance starts at t = 0 again
        command, _ = fmu.step(0.0, estimates()[0], s_bend())
        assert math.isfinite(command.steer_rad)
    finally:
        fmu.close()


def test_a_non_finite_estimate_is_a_safe_stop_and_the_fmu_keeps_time(
        c_fmus: dict[int, Path]) -> None:
    config = TrackerConfig(name=f"fmu:{c_fmus[2]}")
    fmu = FmuTracker(config, PERIOD_S)
    first, second, third = estimates()[:3]
    broken = Estimate(second.t_s, second.names, np.full(len(second.names), np.nan),
                      second.covariance)
    try:
        held, _ = fmu.step(0.0, first, s_bend())
        command, plan = fmu.step(PERIOD_S, broken, s_bend())
        assert (command.steer_rad, command.accel_mps2) == (held.steer_rad,
                                                           config.safe_stop_accel_mps2)
        assert plan.fallback and plan.status == "non_finite_estimate"
        fmu.step(2 * PERIOD_S, third, s_bend())  # the FMU's clock went on
    finally:
        fmu.close()


def test_every_run_removes_the_extracted_fmu(c_fmus: dict[int, Path], tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    made: list[Path] = []
    original = tempfile.mkdtemp

    def mkdtemp(prefix: str) -> str:
        made.append(Path(original(prefix=prefix, dir=tmp_path)))
        return str(made[-1])

    monkeypatch.setattr(slave_module, "_make_unzip_dir", mkdtemp)
    config = load_config("lane-change", tracker=f"fmu:{c_fmus[2]}", duration_s=0.2)
    result = run(config, tmp_path / "run.mcap")
    assert result.completed
    failing = load_config("lane-change", tracker=f"fmu:{c_fmus[2]}", duration_s=0.2,
                          overrides=["tracker.fmu.parameters.fail_at_s=0.1"])
    assert not run(failing, tmp_path / "failed.mcap").completed
    assert len(made) == 2 and not any(path.exists() for path in made)
