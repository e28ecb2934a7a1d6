"""The steering driven by the controller's commands (estimation/steering_model.py,
estimation/steering_commands.py): the timeline, the model, and a start that gates nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.simulation.runner import run_unlogged
from cosim.simulation.scenario_config import load_config
from cosim.simulation.workshop import Workshop
from estimation.bicycle import BicycleParams
from estimation.fusion import KalmanFusion
from estimation.process_model import ProcessModel
from estimation.state import STATE_NAMES, state_index
from estimation.steering_commands import SteeringCommands
from estimation.steering_model import RATE_RELAXATION_S, SteeringBelief
from tests.estimation.test_models import BELIEF, CONFIG, NOISE, ROLL

STEER, RATE = state_index("steer_rad"), state_index("steer_rate_radps")


def test_a_prediction_runs_piece_by_piece_along_the_commands() -> None:
    commands = SteeringCommands()
    assert commands.at(0.0) is None
    assert commands.pieces(0.0, 0.01, 0.01) == [(0.01, None)]
    commands.add(0.05, 0.1)
    commands.add(0.1, -0.2)
    assert commands.at(0.049) is None and commands.at(0.05) == 0.1 and commands.at(0.2) == -0.2
    # Split where a command starts strictly inside; a command at either end does not split.
    pieces = commands.pieces(0.0, 0.12, 0.12)
    assert [c for _, c in pieces] == [None, 0.1, -0.2]
    assert [d for d, _ in pieces] == pytest.approx([0.05, 0.05, 0.02])
    assert commands.pieces(0.05, 0.1, 0.05) == [(0.05, 0.1)]
    commands.add(0.1, -0.3)  # the same instant: the later command wins
    assert commands.at(0.1) == -0.3
    with pytest.raises(ValueError, match="time order"):
        commands.add(0.07, 0.0)
    with pytest.raises(ValueError, match="finite"):
        commands.add(0.2, math.nan)
    with pytest.raises(ValueError, match="the filter is at 0.5 s already"):
        commands.add(0.2, 0.0, not_before_s=0.5)
    commands.add(30.0, 0.0)  # older commands than KEEP_S before it go, the one acting stays
    assert commands.at(25.0) == -0.3


def _model() -> ProcessModel:
    return ProcessModel(NOISE, BicycleParams.from_vehicle(BELIEF, "saturating", ROLL),
                        CONFIG.lateral_residual_time_constant_s,
                        steering=SteeringBelief(time_constant_s=0.05, max_rate_radps=0.8))


def test_without_a_command_the_rate_is_a_random_walk_and_with_one_the_lag_drives() -> None:
    x = np.zeros(len(STATE_NAMES))
    x[state_index("vx_mps")], x[STEER], x[RATE] = 15.0, 0.01, 0.2
    f, a = _model().derivative(x)
    assert f[STEER] == 0.2 and f[RATE] == 0.0 and a[STEER, RATE] == 1.0
    f, a = _model().derivative(x, command_rad=0.02)
    assert f[STEER] == pytest.approx((0.02 - 0.01) / 0.05, rel=1e-5)  # the smooth limit
    assert a[STEER, RATE] == 0.0 and a[STEER, STEER] == pytest.approx(-1.0 / 0.05, rel=1e-4)


def test_commanded_steering_follows_the_actuators_lag_and_rate_limit() -> None:
    model = _model()
    x = np.zeros(len(STATE_NAMES))
    x[state_index("vx_mps")] = 15.0
    steps, dt_s = 20, 0.01
    for _ in range(steps):
        x = model.step(x, dt_s, 0.02)[0].reshape(-1)
    lag = 0.02 * (1.0 - math.exp(-steps * dt_s / 0.05))  # the plant's first-order lag
    assert x[STEER] == pytest.approx(lag, rel=1e-3)
    # The rate state relaxes to the lag's rate 0.4 exp(-t / 0.05) with tau_r = 0.01 s.
    t_s, tau_r = steps * dt_s, RATE_RELAXATION_S
    relaxed = 0.4 * 0.05 / (0.05 - tau_r) * (math.exp(-t_s / 0.05) - math.exp(-t_s / tau_r))
    assert x[RATE] == pytest.approx(relaxed, rel=0.02)
    x[STEER] = 0.0
    fast = model.step(x, dt_s, 0.3)[0].reshape(-1)  # 6 rad/s asked: the limit's 0.8
    assert 0.8 * dt_s * 0.99 < fast[STEER] < 0.8 * dt_s * 1.01


# Seeds at whose start the controller's corrective steering reverses within 0.15 s; a
# filter not told the commands gated its steering sensor there (gnss suite).
REVERSING_SEEDS = (5306, 5313)


def _gated_at_start(monkeypatch: pytest.MonkeyPatch | None) -> list[int]:
    if monkeypatch is not None:  # the filter not told: its steering a random walk again
        monkeypatch.setattr(KalmanFusion, "command", lambda self, t_s, steer_rad: None)
    workshop = Workshop()
    return [run_unlogged(load_config("lane-change", seed=seed, duration_s=1.5,
                                     overrides=["sensors.suite=gnss"]),
                         workshop=workshop).metrics["gated_first_s_steering"]
            for seed in REVERSING_SEEDS]


def test_told_the_commands_the_filter_gates_nothing_at_the_start(
        monkeypatch: pytest.MonkeyPatch) -> None:
    assert _gated_at_start(None) == [0, 0]
    assert sum(_gated_at_start(monkeypatch)) >= 3
