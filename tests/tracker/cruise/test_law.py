"""The ACC law: modes, limits, lost targets, its ESC and its config, one step at a time."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from cosim.core.config_fields import from_dict
from cosim.core.records import Command, Estimate, Plan
from cosim.core.traffic_records import RangeReading
from tracker.cruise.config import AccConfig
from tracker.cruise.esc import EscTuningWarning
from tracker.cruise.law import AccTracker
from tracker.paths.reference_path import ReferencePath

PERIOD_S = 0.05


class Straight:
    """A lateral tracker that steers straight (the ACC's longitudinal law is under test)."""

    def step(self, t_s: float, estimate: Estimate,
             reference: ReferencePath) -> tuple[Command, Plan]:
        plan = Plan(t_s=t_s, dt_s=PERIOD_S, state_names=("vx_mps",), states=np.zeros((2, 1)),
                    input_names=("accel_mps2",), inputs=np.zeros((1, 1)), cost=0.0,
                    solve_time_s=0.0, iterations=0, status="ok", success=True,
                    fallback=False)
        return Command(t_s, 0.7, 0.01), plan


def estimate(speed_mps: float) -> Estimate:
    return Estimate(t_s=0.0, names=("vx_mps",), mean=np.array([speed_mps]),
                    covariance=np.eye(1))


def acc(**settings: object) -> AccTracker:
    config = from_dict(AccConfig, {"enabled": True, **settings})
    return AccTracker(Straight(), config, PERIOD_S)


def settle(tracker: AccTracker, speed_mps: float, steps: int = 200,
           reading: RangeReading | None = None) -> Command:
    command = None
    for k in range(steps):
        t_s = k * PERIOD_S
        if reading is not None:
            tracker.observe_range(RangeReading(t_s, reading.target, reading.gap_m,
                                               reading.range_rate_mps))
        command, _ = tracker.step(t_s, estimate(speed_mps), None)  # type: ignore[arg-type]
    assert command is not None
    return command


def test_without_a_target_it_cruises_on_the_speed_law_and_keeps_the_steering() -> None:
    tracker = acc(k_v=0.3, set_speed_mps=30.0, esc={"enabled": False})
    command = settle(tracker, 28.0)
    assert command.accel_mps2 == pytest.approx(0.3 * 2.0)
    assert command.steer_rad == 0.01
    assert tracker.status is not None and tracker.status.mode == "speed"


def test_a_close_target_switches_to_the_gap_law() -> None:
    tracker = acc(k_v=0.3, k_x=0.1, k_vrel=0.5, time_gap_s=1.8, standstill_gap_m=5.0,
                  set_speed_mps=30.0, esc={"enabled": False})
    # desired gap 5 + 1.8 * 20 = 41 m; at 35 m and closing at 1 m/s:
    command = settle(tracker, 20.0, reading=RangeReading(0.0, "lead", 35.0, -1.0))
    assert tracker.status is not None and tracker.status.mode == "gap"
    assert command.accel_mps2 == pytest.approx(0.1 * (35.0 - 41.0) + 0.5 * -1.0)


def test_a_far_target_leaves_it_in_speed_mode() -> None:
    tracker = acc(k_v=0.3, k_x=0.1, k_vrel=0.5, set_speed_mps=30.0, esc={"enabled": False})
    command = settle(tracker, 28.0, reading=RangeReading(0.0, "lead", 150.0, 0.0))
    assert tracker.status is not None and tracker.status.mode == "speed"
    assert command.accel_mps2 == pytest.approx(0.3 * 2.0)


def test_jerk_and_acceleration_limits_hold() -> None:
    tracker = acc(k_x=1.0, k_vrel=1.0, jerk_max_mps3=2.0, accel_min_mps2=-3.0,
                  esc={"enabled": False})
    reading = RangeReading(0.0, "lead", 10.0, -10.0)  # far too close, closing fast
    accels = []
    for k in range(60):
        tracker.observe_range(RangeReading(k * PERIOD_S, "lead", reading.gap_m, -10.0))
        command, _ = tracker.step(k * PERIOD_S, estimate(20.0), None)  # type: ignore[arg-type]
        accels.append(command.accel_mps2)
    steps = np.diff([0.0, *accels])
    assert np.all(np.abs(steps) <= 2.0 * PERIOD_S + 1e-12)
    assert min(accels) == pytest.approx(-3.0)
    assert accels[9] == pytest.approx(-2.0 * PERIOD_S * 10)  # ramping at the jerk limit


def test_a_dropped_target_is_extrapolated_then_forgotten() -> None:
    tracker = acc(k_x=0.1, k_vrel=0.5, range_timeout_s=0.5, esc={"enabled": False})
    tracker.observe_range(RangeReading(0.0, "lead", 30.0, -2.0))
    settle(tracker, 20.0, steps=1)
    tracker.step(0.3, estimate(20.0), None)  # type: ignore[arg-type]
    status = tracker.status
    assert status is not None and status.target == "lead"
    assert status.gap_m == pytest.approx(30.0 - 2.0 * 0.3)
    tracker.step(0.6, estimate(20.0), None)  # type: ignore[arg-type]
    assert tracker.status is not None and tracker.status.target == ""
    assert tracker.status.mode == "speed"


def test_no_target_reading_means_speed_mode() -> None:
    tracker = acc(esc={"enabled": False})
    settle(tracker, 20.0, reading=RangeReading(0.0, "", math.nan, math.nan))
    assert tracker.status is not None and tracker.status.mode == "speed"


def test_esc_moves_only_the_active_laws_gains() -> None:
    tracker = acc(k_v=0.4, k_x=0.05, k_vrel=0.4, set_speed_mps=30.0,
                  esc={"k_v": {"step": 5.0}, "max_speed_error_mps": 50.0})
    settle(tracker, 25.0, steps=600)  # speed mode only: no target
    status = tracker.status
    assert status is not None
    k_v, k_x, k_vrel = status.gain_estimates
    assert k_v != 0.4
    assert (k_x, k_vrel) == (0.05, 0.4)


def test_without_esc_the_gains_stay() -> None:
    tracker = acc(k_v=0.4, k_x=0.05, k_vrel=0.4, esc={"enabled": False})
    settle(tracker, 20.0, reading=RangeReading(0.0, "lead", 35.0, -1.0))
    assert tracker.status is not None and tracker.status.gains == (0.4, 0.05, 0.4)


def test_the_default_tuning_breaks_no_rule() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        acc()


def test_a_breached_rule_warns_at_start() -> None:
    with pytest.warns(EscTuningWarning, match="high-pass cut-off below the perturbation"):
        acc(esc={"highpass_radps": 0.5})


def test_the_objective_penalises_gap_error_speed_error_and_jerk() -> None:
    tracker = acc(k_x=0.1, k_vrel=0.5, weight_gap=2.0, weight_speed=3.0, weight_jerk=0.0,
                  time_gap_s=1.0, standstill_gap_m=5.0, esc={"enabled": False})
    settle(tracker, 20.0, reading=RangeReading(0.0, "lead", 20.0, -1.0))
    status = tracker.status
    assert status is not None and status.mode == "gap"
    assert status.objective == pytest.approx(2.0 * (20.0 - 25.0) ** 2 + 3.0 * 1.0**2)


def test_setting_one_esc_key_keeps_that_gains_other_defaults() -> None:
    config = from_dict(AccConfig, {"esc": {"k_x": {"step": 0.5}}})
    default = AccConfig().esc
    assert config.esc.k_x.step == 0.5
    assert config.esc.k_x.frequency_radps == default.k_x.frequency_radps
    assert len({default.k_v.frequency_radps, default.k_x.frequency_radps,
                default.k_vrel.frequency_radps}) == 3


def test_an_initial_gain_outside_the_esc_bounds_is_refused() -> None:
    from cosim.core.exceptions import ConfigError

    with pytest.raises(ConfigError, match="k_x = 2: expected within esc.k_x.low"):
        from_dict(AccConfig, {"k_x": 2.0})
    assert from_dict(AccConfig, {"k_x": 2.0, "esc": {"enabled": False}}).k_x == 2.0


@pytest.mark.parametrize(("k_x", "k_vrel"), [(0.02, 0.3), (0.1, 0.6), (0.5, 0.2)])
def test_the_loop_modes_are_the_design_models_poles(k_x: float, k_vrel: float) -> None:
    """Gap mode: the roots of s^2 + (K_vrel + h K_x) s + K_x; speed mode: K_v."""
    from tracker.cruise.law import loop_modes_radps

    k_v, slow, fast = loop_modes_radps(0.4, k_x, k_vrel, 1.8)
    poles = np.abs(np.roots([1.0, k_vrel + 1.8 * k_x, k_x]))
    assert k_v == 0.4
    assert (slow, fast) == pytest.approx(sorted(poles))


def test_a_gap_gain_perturbed_faster_than_its_loop_mode_warns() -> None:
    """With K_x = 0.02, K_vrel = 0.3 the slow gap mode is at 0.077 rad/s: K_x perturbed at
    0.13 rad/s breaches time-scale separation, at 0.035 rad/s it does not."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        acc(k_x=0.02, k_vrel=0.3, esc={"k_x": {"frequency_radps": 0.13}})
    messages = [str(w.message) for w in caught if w.category is EscTuningWarning]
    assert "extremum seeking: rule 'perturbation slower than the plant': k_x omega = 0.13 " \
           "rad/s is not below the frequency of the plant's mode it acts through, " \
           "0.07731 rad/s" in messages
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        acc(k_x=0.02, k_vrel=0.3, esc={"k_x": {"frequency_radps": 0.035}})


def test_log_and_mean_normalisation_are_exclusive() -> None:
    from cosim.core.exceptions import ConfigError

    with pytest.raises(ConfigError, match="log_objective = true and normalise_by_mean = true"):
        from_dict(AccConfig, {"esc": {"log_objective": True}})
    assert from_dict(AccConfig, {"esc": {"log_objective": True,
                                         "normalise_by_mean": False}}).esc.log_objective
