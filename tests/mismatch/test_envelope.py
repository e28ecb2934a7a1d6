"""Robustness envelope of the default tracker on the double lane change at 20 m/s.

The default loop (``dynamic-nmpc`` with the EKF, RTK sensors) on the full 15 s
``lane-change`` scenario (peak 0.5 g), seed 0, with one thing wrong at a time: the real car
(``plant.*``) or the sensors differ from what the controller believes (``tracker.model.*``,
held at the nominal sedan: 1575 kg, friction 1.0). Each case states what the loop must still
achieve, or, beyond the envelope, that the run completes and the metrics show the failure.

How the bounds were set (measured with ``cosim run lane-change --seed S --set ...`` for
seeds 0, 1, 2 on the code of issue 6; the nominal run gives a max CTE of 0.058 / 0.046 /
0.047 m): an upper bound is 1.5 times the worst of the three seeds, rounded up to the next
0.05 m, so seed noise and small tuning changes pass while a real loss of robustness (the
failures below are metres, not centimetres) does not. Every in-envelope run measured needed
no solver fallback, so none is allowed.

About 11 runs of 6-8 s each: marked ``slow`` (``make test`` runs them, ``make test-fast``
does not) and ``mismatch`` (``pytest -m mismatch`` runs this suite alone).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.core.config_fields import to_dict
from cosim.simulation.beliefs import mismatch_table
from cosim.simulation.runner import RunResult
from cosim.simulation.scenario_config import load_config
from tests.conftest import run_scenario

pytestmark = [pytest.mark.mismatch, pytest.mark.slow]

NOMINAL_MASS_KG = 1575.0
"""The sedan's mass, the plant's default and the controller's belief."""


def lane_change(tmp_path: Path, *overrides: str) -> RunResult:
    """The full lane change, seed 0, with ``overrides`` on top of the defaults (no log: the
    tests here read the metrics)."""
    return run_scenario(tmp_path, "lane-change", *overrides, logged=False)


def assert_tracks(result: RunResult, cte_bound_m: float) -> None:
    metrics = result.metrics
    assert result.completed and metrics["completed"] is True
    assert metrics["outcome"] == "ok", metrics["outcome"]
    assert metrics["solver_failures"] == 0
    assert metrics["cte_max_m"] <= cte_bound_m, metrics["cte_max_m"]


def test_car_30_percent_heavier_than_believed(tmp_path: Path) -> None:
    """Plant 2047.5 kg (+30 %), belief 1575 kg: max CTE <= 0.20 m.

    Measured 0.124 / 0.109 / 0.088 m (seeds 0/1/2): the low-level layer converts the
    demanded acceleration into torque with the believed mass, so the heavier car accelerates
    30 % less than planned and corners with more inertia; the MPC's feedback absorbs it.
    Bound 1.5 x 0.124 = 0.19 -> 0.20 m.
    """
    result = lane_change(tmp_path, f"plant.mass_kg={NOMINAL_MASS_KG * 1.3}")
    assert_tracks(result, cte_bound_m=0.20)


def test_car_30_percent_lighter_than_believed(tmp_path: Path) -> None:
    """Plant 1102.5 kg (-30 %), belief 1575 kg, dry road: max CTE <= 0.20 m.

    Measured 0.087 / 0.091 / 0.114 m. Bound 1.5 x 0.114 = 0.17 -> 0.20 m. (On a slippery
    road this is the dangerous direction: the believed mass makes the drive torque 43 % too
    large on the rear axle; ``examples/mass-friction.yaml`` shows the 1100 kg car spinning at
    friction 0.7 and 0.8, where the nominal car does not.)
    """
    result = lane_change(tmp_path, f"plant.mass_kg={NOMINAL_MASS_KG * 0.7}")
    assert_tracks(result, cte_bound_m=0.20)


def test_tyre_road_friction_0_7(tmp_path: Path) -> None:
    """``plant.tyre_friction=0.7`` (nominal 1.0, belief 1.0): max CTE <= 0.15 m.

    Measured 0.095 / 0.075 / 0.062 m (0.8: 0.075 / 0.057 / 0.052 m). Bound 1.5 x 0.095 =
    0.14 -> 0.15 m. 0.7 is the lowest friction inside the envelope *while the belief says
    1.0*: at 0.6 the car spins (see :func:`test_friction_beyond_the_envelope_fails_visibly`).
    A tracker that knows the friction holds the lane change down to 0.5
    (:func:`test_friction_0_6_known_to_the_tracker`, :func:`test_friction_0_5_known_slows_down`).
    """
    result = lane_change(tmp_path, "plant.tyre_friction=0.7")
    assert_tracks(result, cte_bound_m=0.15)


def test_friction_0_6_known_to_the_tracker(tmp_path: Path) -> None:
    """Friction 0.6 on the road and in the belief: no spin, max CTE <= 0.10 m.

    The friction-aware ``dynamic-nmpc`` (``tracker.grip``, on by default) keeps each axle's
    planned force within 0.85 of ``mu F_z`` (:mod:`tracker.models.tyre_limits`): it accelerates from
    15 to 20 m/s at about 2.2 m/s^2 instead of the 3 m/s^2 that spun the rear wheels and
    turned the car round (max CTE 11.3 m before). The lane change's 0.5 g fits within 0.85
    of 0.6 g, so the speed is not reduced. Its model's tyres saturate at the friction
    (``grip.saturating_tyres``): measured 0.049 / 0.063 / 0.048 / 0.060 / 0.047 m (seeds 0-4,
    2026-12-08), no fallback. Bound 1.5 x 0.063 = 0.094 -> 0.10 m. With the linear tyres
    (``grip.saturating_tyres=false``) the controller steers too little near the limit:
    0.294 / 0.223 / 0.219 / 0.300 / 0.248 m (held-out seeds 6800-6819: median 0.274 m, worst
    0.404 m, against 0.062 and 0.086 m).
    """
    result = lane_change(tmp_path, "plant.tyre_friction=0.6", "tracker.model.tyre_friction=0.6")
    assert_tracks(result, cte_bound_m=0.10)
    assert result.metrics["speed_reduced_steps"] == 0


def test_friction_0_6_the_controller_alone(tmp_path: Path) -> None:
    """The same lane change with the true state as the estimate (``estimator.name=truth``):
    what the controller's model alone is worth at the limit. Its saturating tyres: 0.054 m;
    the linear ones ran the car 0.368 m off the path (the filter's errors had hidden it:
    0.294 m with them). Bound 1.5 x 0.054 = 0.081 -> 0.10 m.
    """
    result = lane_change(tmp_path, "plant.tyre_friction=0.6", "tracker.model.tyre_friction=0.6",
                         "estimator.name=truth")
    assert_tracks(result, cte_bound_m=0.10)


def test_friction_0_5_known_slows_down(tmp_path: Path) -> None:
    """Friction 0.5, known: the 0.5 g bends need all the grip at 20 m/s, so the tracker
    slows down before them (:mod:`tracker.mpc.grip_speed`) and says so in its plans.

    Measured: ``speed_reduced`` in 64 of 300 plans (2.9-6.05 s), the car down to 18.4 m/s,
    max CTE 0.146 / 0.144 / 0.169 / 0.128 / 0.160 m (seeds 0-4, 2026-12-08; 0.292 / 0.309 /
    0.242 / 0.326 / 0.247 m with the model's tyres linear, ``grip.saturating_tyres=false``),
    no fallback. Bound 1.5 x 0.169 = 0.25 m; the speed reduction must be reported and must
    not stop the car
    (more than 10 % of the steps reduced would mean the cap is far too cautious:
    the bends take 3 s of the 15).
    """
    result = lane_change(tmp_path, "plant.tyre_friction=0.5", "tracker.model.tyre_friction=0.5")
    assert_tracks(result, cte_bound_m=0.25)
    steps = result.metrics["speed_reduced_steps"]
    assert 10 <= steps <= 100, steps
    assert result.metrics["speed_err_rms_mps"] < 2.0, result.metrics["speed_err_rms_mps"]


def test_light_car_on_a_wet_road_with_slip_control(tmp_path: Path) -> None:
    """The 1102.5 kg car believed to weigh 1575 kg on friction 0.7: the low-level layer asks
    43 % too much drive torque, and without slip control the rear wheels spin and the car
    turns round (outcome spun at 3.3 s, max CTE 22 m: the old behaviour, kept with
    ``plant.slip_control.enabled=false``, the default). With the car's traction control
    (:mod:`cosim.plant.slip_control`) it tracks: measured 0.101 / 0.092 / 0.108 / 0.136 /
    0.113 m (seeds 0-4). Traction control alone also saves the nominal car on friction 0.6
    with the belief at 1.0 (0.166 m, seed 0), which the tracker cannot.
    Bound 0.30 m, the mass-friction sweep's pass mark.
    """
    light = f"plant.mass_kg={NOMINAL_MASS_KG * 0.7}"
    result = lane_change(tmp_path, light, "plant.tyre_friction=0.7",
                         "plant.slip_control.enabled=true")
    assert_tracks(result, cte_bound_m=0.30)


def test_actuator_delay_150_ms_told_to_the_tracker(tmp_path: Path) -> None:
    """``plant.actuator_delay_s=0.15`` with ``tracker.latency_s=plant``: the side varied
    is the plant's, and the tracker is told it (a known delay, not a mismatch).

    The tracker predicts over the delay (``tracker.latency_compensation`` is on by
    default), so the MPC plans from the state the car will be in when the command lands.
    Measured 0.082 / 0.062 / 0.063 m, barely above nominal. Bound 1.5 x 0.082 = 0.12 ->
    0.15 m. A delay the tracker is not told is another question (the next test).
    """
    overrides = ("plant.actuator_delay_s=0.15", "tracker.latency_s=plant")
    config = load_config("lane-change", overrides=list(overrides))
    assert config.tracker.latency_s == 0.15 and config.tracker.latency_compensation
    assert config.beliefs_from_plant == {"tracker.latency_s": "plant.actuator_delay_s"}
    result = lane_change(tmp_path, *overrides)
    assert_tracks(result, cte_bound_m=0.15)


def test_an_unknown_actuator_delay_is_a_mismatch() -> None:
    """``plant.actuator_delay_s`` alone varies the plant's side only: the tracker's belief
    stays the nominal car's (no delay), and the mismatch table says so."""
    config = load_config("lane-change", overrides=["plant.actuator_delay_s=0.15"])
    assert config.tracker.latency_s == 0.0 and config.beliefs_from_plant == {}
    (row,) = mismatch_table(to_dict(config))
    assert (row.quantity, row.plant, row.belief) == ("actuator_delay_s", 0.15, 0.0)


def test_gnss_sigma_0_5_m(tmp_path: Path) -> None:
    """``sensors.gnss.sigma_m=0.5`` (RTK's is 0.02 m): max CTE <= 0.75 m, position RMSE
    <= 0.35 m.

    The filter fuses 10 Hz fixes 25 times noisier than RTK with the IMU and wheel speeds;
    the tracker follows the estimate, so the estimate's error is the tracking error's floor.
    Measured max CTE 0.349 / 0.499 / 0.271 m and estimate position RMSE 0.205 / 0.226 /
    0.177 m. Bounds 1.5 x 0.499 = 0.75 m and 1.5 x 0.226 = 0.34 -> 0.35 m.
    """
    # The receiver is worse and the filter knows it (its belief, estimator.noise, is set
    # apart from the sensor's truth: a belief left at RTK's 0.02 m is another question).
    result = lane_change(tmp_path, "sensors.gnss.sigma_m=0.5", "estimator.noise.gnss_sigma_m=0.5")
    assert_tracks(result, cte_bound_m=0.75)
    assert result.metrics["est_pos_rmse_m"] <= 0.35, result.metrics["est_pos_rmse_m"]


@pytest.mark.parametrize("friction", [0.6, 0.3])
def test_friction_beyond_the_envelope_fails_visibly(tmp_path: Path, friction: float) -> None:
    """Friction 0.6 and 0.3 at 20 m/s *with the belief at 1.0*: tracking must fail, and the
    metrics must say so.

    The rear-driven car accelerates from 15 to 20 m/s at the 3 m/s^2 bound, which a belief
    of friction 1.0 allows (67 % of the rear axle's believed grip; ``tracker.grip`` adds its
    tyre limits only below a believed 0.9); on 0.6 the rear wheels spin and the car turns
    round: max CTE 10.7 / 11.1 /
    11.0 m, heading error pi (seeds 0/1/2), 12.2 / 12.5 / 12.4 m at 0.3. This stays the
    case after the friction-aware tracker (28.0 m at 0.6, seed 0): it can only respect the
    friction it believes in. When the belief knows 0.6 the car tracks
    (:func:`test_friction_0_6_known_to_the_tracker`; before the tyre limits it spun there
    too, 11.3 m). The run stops at the spin (outcome ``spun``, ``completed: false``; with
    ``outcome.keep_going`` it would drive on, turned round), and the failure shows in the
    outcome and a body slip or heading error beyond the spin thresholds.
    """
    result = lane_change(tmp_path, f"plant.tyre_friction={friction}")
    assert not result.completed and "stopped at spun" in result.abort_reason
    assert result.metrics["outcome"] == "spun", result.metrics["outcome"]  # it turned round
    assert result.metrics["sim_duration_s"] == result.metrics["spun_t_s"] < 15.0
