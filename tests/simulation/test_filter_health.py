"""The end-of-run alarm for an inconsistent filter (:mod:`cosim.simulation.filter_health`)."""

from __future__ import annotations

from cosim.simulation.filter_health import filter_warnings

CONSISTENT = {"sim_duration_s": 15.0, "nees_mean": 4.3, "nis_gnss": 1.1, "nis_dof_gnss": 300,
              "nis_wheel_speed": 0.9, "nis_dof_wheel_speed": 3000, "channels_gated": 2}


def test_a_consistent_run_says_nothing() -> None:
    assert filter_warnings(CONSISTENT, set()) == []


def test_nees_far_above_its_dof_is_an_alarm_with_the_gated_channels() -> None:
    (what, value, threshold, line), = filter_warnings({**CONSISTENT, "nees_mean": 21.3,
                                                       "channels_gated": 157}, set())
    assert (what, value, threshold) == ("nees_mean", 21.3, 10.0)
    assert "nees_mean 21.3" in line and "157 measurement channels gated" in line
    assert "2.3 times" in line  # sqrt(21.3 / 4)


def test_a_sensor_out_of_band_is_named_unless_the_belief_check_did() -> None:
    metrics = {**CONSISTENT, "nis_wheel_speed": 3.52}
    (what, *_), = filter_warnings(metrics, set())
    assert what == "nis_wheel_speed"
    assert filter_warnings(metrics, {"wheel_speed"}) == []
    assert filter_warnings({**metrics, "nis_dof_wheel_speed": 5}, set()) == []  # too few


def test_a_short_run_is_not_judged() -> None:
    assert filter_warnings({**CONSISTENT, "nees_mean": 30.0, "sim_duration_s": 1.0}, set()) == []
