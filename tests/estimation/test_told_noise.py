"""The process noise of a filter told the controller's commands
(:func:`estimation.belief_models.told_process_noise`): each command stream replaces the
random walk's PSD of the state it drives, and only that one, from its first command on."""

from __future__ import annotations

import pytest

from cosim.core.initial_state import InitialState
from estimation.config import EstimatorConfig
from estimation.ekf import Ekf
from estimation.state import STATE_NAMES, state_index
from estimation.ukf import Ukf
from tests.estimation.test_models import BELIEF

STEER, AX = state_index("steer_rad"), state_index("ax_mps2")


@pytest.mark.parametrize("kind", [Ekf, Ukf])
def test_each_command_stream_replaces_its_own_states_noise(kind: type[Ekf | Ukf]) -> None:
    """Untold, the steering's PSD is ``steer_psd_rad2ps`` (the random walk follows every
    swerve); from the first steering command ``steer_commanded_psd_rad2ps``; an
    acceleration command changes the jerk's alone; every other state's PSD is untouched;
    a restart forgets both."""
    config = EstimatorConfig(initial="truth")
    assert config.steer_commanded_psd_rad2ps < config.steer_psd_rad2ps
    initial = InitialState(x_m=0.0, y_m=0.0, yaw_rad=0.0, speed_mps=15.0)
    f = kind(config, initial, BELIEF)
    state = f.estimate().mean.copy()

    def psd() -> list[float]:
        return [float(v) for v in f._process.noise_psd(state).diagonal()]

    untold = psd()
    assert untold[STEER] == pytest.approx(config.steer_psd_rad2ps, rel=1e-12)
    f.command(0.0, 0.01)
    told = psd()
    assert told[STEER] == pytest.approx(config.steer_commanded_psd_rad2ps, rel=1e-12)
    assert [v for i, v in enumerate(told) if i != STEER] == \
        [v for i, v in enumerate(untold) if i != STEER]
    f.command(0.02, 0.02)  # a second command changes nothing more
    assert psd() == told
    f.accel_command(0.02, 1.0)
    both = psd()
    assert both[STEER] == told[STEER]
    assert both[AX] == pytest.approx(config.accel_commanded_jerk_psd_m2ps5, rel=1e-12)
    assert [v for i, v in enumerate(both) if i not in (STEER, AX)] == \
        [v for i, v in enumerate(untold) if i not in (STEER, AX)]
    f.restart(initial)
    assert psd() == untold
    f.accel_command(0.0, 1.0)  # the other order: the jerk's first, the steering's untold
    only_accel = psd()
    assert only_accel[STEER] == untold[STEER] and only_accel[AX] == both[AX]
    assert len(untold) == len(STATE_NAMES)
