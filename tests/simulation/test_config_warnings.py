"""Mis-configuration made visible: a key the run does not read, a key that moved, and a
filter whose belief about a sensor disagrees with the sensor."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.cli import main
from cosim.core.exceptions import ConfigError
from cosim.log.reader import iter_messages
from cosim.simulation.belief_check import belief_mismatches
from cosim.simulation.scenario_config import load_config
from cosim.simulation.unread_keys import UnreadKeyWarning, unread_key_warnings


def test_a_key_the_tracker_does_not_read_names_who_does() -> None:
    data = {"tracker": {"horizon": 80, "weights": {"cte": 1000}, "dynamic_mpc": {
        "prediction_horizon": 12}}}
    lines = unread_key_warnings(data, "dynamic-mpc", "pacejka")
    assert lines == [
        "tracker.horizon = 80 is not read by tracker dynamic-mpc: it is read by tracker "
        "kinematic-nmpc, dynamic-nmpc, ltv-mpc",
        "tracker.weights.cte = 1000 is not read by tracker dynamic-mpc: it is read by "
        "tracker kinematic-nmpc, dynamic-nmpc, ltv-mpc"]
    # The NMPC reads both and not dynamic_mpc.*; a plug-in may read anything.
    assert unread_key_warnings(data, "dynamic-nmpc", "pacejka") == [
        "tracker.dynamic_mpc.prediction_horizon = 12 is not read by tracker dynamic-nmpc: "
        "it is read by tracker dynamic-mpc"]
    assert unread_key_warnings(data, "my_pkg.mod:Mine", "pacejka") == []
    baseline = {"tracker": {"baseline": {"lqr": {"q_cte": 2.0}, "speed": {"kp": 1.0}}}}
    assert unread_key_warnings(baseline, "lqr", "pacejka") == []
    assert unread_key_warnings(baseline, "pid", "pacejka") == [
        "tracker.baseline.lqr.q_cte = 2.0 is not read by tracker pid: it is read by "
        "tracker lqr"]


def test_a_grip_setting_only_the_dynamic_nmpc_reads_names_it() -> None:
    """The friction ellipse and the saturating tyres are the dynamic NMPC's alone; the
    kinematic NMPC plans its speed by the grip too, and reads those keys."""
    data = {"tracker": {"grip": {"saturating_tyres": False, "tyre_limits": False,
                                 "usage_max": 0.7}}}
    assert unread_key_warnings(data, "dynamic-nmpc", "pacejka") == []
    assert unread_key_warnings(data, "kinematic-nmpc", "pacejka") == [
        "tracker.grip.saturating_tyres = False is not read by tracker kinematic-nmpc: it is "
        "read by tracker dynamic-nmpc",
        "tracker.grip.tyre_limits = False is not read by tracker kinematic-nmpc: it is read "
        "by tracker dynamic-nmpc"]
    assert len(unread_key_warnings(data, "ltv-mpc", "pacejka")) == 3


def test_a_path_key_the_path_does_not_read_names_who_does() -> None:
    """path.seed on a track (a file's circuit) was ignored without a word."""
    with pytest.warns(UnreadKeyWarning, match=r"path.seed = 7 is not read by path.kind "
                      r"track .*: it is read by path.kind generated"):
        load_config("track", overrides=["path.seed=7"])
    lines = unread_key_warnings({"path": {"kind": "circle", "cruise_s": 9.0,
                                          "radius_m": 30.0}}, "dynamic-nmpc", "pacejka")
    assert lines == ["path.cruise_s = 9.0 is not read by path.kind circle with "
                     "path.speed_profile constant: it is read by path.speed_profile "
                     "stop-and-go"]


def test_a_key_at_its_default_is_not_reported() -> None:
    # A whole configuration (cosim config show) names every key at its default.
    defaults = {"tracker": {"horizon": 25}}
    data = {"tracker": {"horizon": 25}}
    assert unread_key_warnings(data, "dynamic-mpc", "pacejka", defaults=defaults) == []
    data = {"tracker": {"horizon": 80}}
    assert len(unread_key_warnings(data, "dynamic-mpc", "pacejka", defaults=defaults)) == 1


def test_load_config_warns_once_per_unread_key() -> None:
    with pytest.warns(UnreadKeyWarning, match="tracker.horizon = 80 is not read"):
        load_config("lane-change", tracker="dynamic-mpc", overrides=["tracker.horizon=80"])


def test_tyre_settings_are_unread_with_contact_tyres() -> None:
    data = {"plant": {"tyre_model": "contact", "tyre": {"lateral_shape": 1.3}}}
    assert unread_key_warnings(data, "dynamic-nmpc", "contact") == [
        "plant.tyre.lateral_shape = 1.3 is not read with plant.tyre_model = contact: the "
        "plant reads it with plant.tyre_model = pacejka"]
    assert unread_key_warnings(data, "dynamic-nmpc", "pacejka") == []


@pytest.mark.parametrize("side", ["front", "rear"])
def test_cornering_stiffness_under_plant_is_refused_with_its_new_name(side: str) -> None:
    with pytest.raises(ConfigError, match=f"tracker.model.cornering_stiffness_{side}_npr"):
        load_config("lane-change",
                    overrides=[f"plant.cornering_stiffness_{side}_npr=50000"])
    config = load_config("lane-change",
                         overrides=[f"tracker.model.cornering_stiffness_{side}_npr=50000"])
    assert not hasattr(config.plant, f"cornering_stiffness_{side}_npr")


def test_the_belief_check_names_the_sensor_and_both_sigmas() -> None:
    config = {"sensors": {"gnss": {"sigma_m": 0.1}, "imu": {"gyro_sigma_radps": 0.005,
                                                           "accel_sigma_mps2": 0.05}},
              "estimator": {"noise": {"gnss_sigma_m": 0.02, "gyro_sigma_radps": 0.005,
                                      "accel_sigma_mps2": 0.05}}}
    metrics = {"nis_gnss": 25.0, "nis_dof_gnss": 600, "nis_imu": 1.1, "nis_dof_imu": 9000}
    (found,) = belief_mismatches(metrics, config)
    assert found.sensor == "gnss" and found.nis == 25.0 and found.bound == 3.0
    assert "sensors.gnss.sigma_m = 0.1" in found.line
    assert "estimator.noise.gnss_sigma_m = 0.02" in found.line
    # Within the band, or too few samples to tell: nothing to say.
    assert belief_mismatches({"nis_gnss": 2.5, "nis_dof_gnss": 600}, config) == []
    assert belief_mismatches({"nis_gnss": 25.0, "nis_dof_gnss": 4}, config) == []
    (low,) = belief_mismatches({"nis_gnss": 0.1, "nis_dof_gnss": 600}, config)
    assert low.bound == 0.3
    # The IMU's figures agree with the belief: its NIS is the filter's model, not a setting.
    assert belief_mismatches({"nis_imu": 11.0, "nis_dof_imu": 900}, config) == []
    # A noise-free sensor (the ideal suite) cannot be believed: no warning for it.
    ideal = {**config, "sensors": {"gnss": {"sigma_m": 0.0}}}
    assert belief_mismatches({"nis_gnss": 0.01, "nis_dof_gnss": 600}, ideal) == []


@pytest.mark.slow
def test_a_wrong_belief_prints_one_warning_and_logs_it(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "wrong.mcap"
    assert main(["run", "lane-change", "--duration", "3", "--set", "sensors.gnss.sigma_m=0.1",
                 "--out", str(out)]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "NIS" in line]
    assert len(warned) == 1 and warned[0].startswith("cosim: warning: gnss NIS per dof")
    events = [m for _, m in iter_messages(out, "/events") if m["kind"] == "belief_mismatch"]
    assert len(events) == 1 and events[0]["value"] > 3.0
    # Sensor and belief set together: consistent, no warning.
    agreed = tmp_path / "agreed.mcap"
    assert main(["run", "lane-change", "--duration", "3", "--set", "sensors.gnss.sigma_m=0.1",
                 "--set", "estimator.noise.gnss_sigma_m=0.1", "--out", str(agreed)]) == 0
    assert "NIS" not in capsys.readouterr().err
