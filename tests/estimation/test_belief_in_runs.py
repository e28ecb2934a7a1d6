"""The filter's belief in a run: its own noise model (estimator.noise), its initial estimate
(estimator.initial), the sensors it needs, and the NIS figures that show a mismatch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from cosim.log.reader import iter_messages
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from tests.cli.test_cli import cosim


def test_suite_sets_the_belief_unless_it_is_set() -> None:
    """A plain run is matched: the gnss suite's receiver is believed to be 0.5 m; a belief
    set explicitly wins over the suite (a mismatch is a config)."""
    assert load_config("lane-change").estimator.noise.gnss_sigma_m == 0.02
    assert load_config("lane-change", overrides=["sensors.suite=gnss"]
                       ).estimator.noise.gnss_sigma_m == 0.5
    config = load_config("lane-change", overrides=[
        "sensors.suite=gnss", "estimator.noise.gnss_sigma_m=0.3"])
    assert config.estimator.noise.gnss_sigma_m == 0.3 and config.sensors.gnss.sigma_m == 0.5
    config = load_config("lane-change", overrides=["sensors.gnss.sigma_m=0.05"])
    assert config.estimator.noise.gnss_sigma_m == 0.02


def test_disabled_sensor_the_estimator_needs_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"sensors\.gnss\.enabled = false: .*ekf"):
        load_config("lane-change", overrides=["sensors.gnss.enabled=false"])
    load_config("lane-change", overrides=["sensors.imu.enabled=false"])  # optional for it
    load_config("lane-change", overrides=["sensors.gnss.enabled=false"], estimator="truth")
    result = cosim("run", "lane-change", "--set", "sensors.gnss.enabled=false",
                   "--estimator", "ukf")
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "sensors.gnss.enabled" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.slow
def test_initial_estimate_is_sampled_without_touching_the_sensor_noise(tmp_path: Path) -> None:
    """The default run starts from a draw around the truth (not the truth), from its own
    generator: the sensors' noise is the same as with ``estimator.initial=truth`` (the
    measurements themselves differ after the first control step: another estimate steers
    the car otherwise)."""
    logs = {}
    for mode in ("sampled", "truth"):
        config = load_config("lane-change", overrides=[f"estimator.initial={mode}"],
                             duration_s=0.2, seed=5)
        logs[mode] = tmp_path / f"{mode}.mcap"
        run(config, logs[mode])
    noise = {}
    for mode, path in logs.items():
        truth = {round(m["t_s"], 6): m for _, m in iter_messages(path, "/vehicle/truth")}
        noise[mode] = np.array([[m["x_m"] - truth[round(m["t_s"], 6)]["x_m"],
                                 m["y_m"] - truth[round(m["t_s"], 6)]["y_m"]]
                                for _, m in iter_messages(path, "/sensors/gnss")])
    assert noise["sampled"].shape == (3, 2)
    np.testing.assert_allclose(noise["sampled"], noise["truth"], rtol=0, atol=1e-9)
    first = {mode: next(iter_messages(path, "/vehicle/estimate"))[1]
             for mode, path in logs.items()}
    truth = next(iter_messages(logs["truth"], "/vehicle/truth"))[1]
    assert first["truth"]["x_m"] == truth["x_m"]
    assert first["sampled"]["x_m"] != truth["x_m"]
    assert first["sampled"]["vx_mps"] != truth["vx_mps"]


@pytest.mark.parametrize("believed_m, low, high", [(0.02, 2.0, np.inf), (0.2, 0.0, 0.5),
                                                   (0.05, 0.6, 1.6)])
@pytest.mark.slow
def test_mismatched_gnss_belief_shows_in_its_nis(believed_m: float, low: float, high: float,
                                                 tmp_path: Path) -> None:
    """GNSS truth 0.05 m; believed 0.02 m (over-confident: NIS per dof far above 1), 0.2 m
    (under-confident: far below) or 0.05 m (matched: near 1). With RTK-class dead reckoning
    the prior's position variance is small against R, so NIS per dof is about
    truth^2 / belief^2: 6, 0.06 and 1."""
    config = load_config("lane-change", duration_s=3.0, seed=7, overrides=[
        "sensors.gnss.sigma_m=0.05", f"estimator.noise.gnss_sigma_m={believed_m}"])
    metrics = run(config, tmp_path / "run.mcap").metrics
    assert metrics["completed"] is True
    assert low < metrics["nis_gnss"] < high
    assert metrics["nis_dof_gnss"] == 2 * 31
