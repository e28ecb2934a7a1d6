"""The tracker's record of its commands on their way to the car (tracker.mpc.delay_line)."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.core.exceptions import ConfigError
from tracker.mpc.delay_line import IssuedInputs


def _line(delay_s: float) -> IssuedInputs:
    """Commands 1, 2, 3 issued at 0.0, 0.05, 0.10 s (one-element inputs)."""
    line = IssuedInputs(delay_s, np.array([0.0]))
    for k, value in enumerate((1.0, 2.0, 3.0)):
        line.record(0.05 * k, np.array([value]))
    return line


def _pieces(line: IssuedInputs, start_s: float, end_s: float) -> list[tuple[float, float]]:
    return [(round(d, 9), float(u[0])) for d, u in line.segments(start_s, end_s)]


def test_without_delay_each_command_applies_when_issued() -> None:
    line = _line(0.0)
    assert line.applied_at(0.0)[0] == 1.0
    assert line.applied_at(0.07)[0] == 2.0
    assert _pieces(line, 0.0, 0.15) == [(0.05, 1.0), (0.05, 2.0), (0.05, 3.0)]


def test_with_delay_the_car_applies_what_was_issued_delay_earlier() -> None:
    line = _line(0.1)
    # Before the first command arrives the car applies the initial input.
    assert line.applied_at(0.099)[0] == 0.0
    assert line.applied_at(0.1)[0] == 1.0
    assert line.applied_at(0.2)[0] == 3.0
    # From 0.1 s (now, the last command just issued) to 0.2 s (now + delay): the two
    # commands still in the line, then the one issued now arrives exactly at the end.
    assert _pieces(line, 0.1, 0.2) == [(0.05, 1.0), (0.05, 2.0)]
    # An interval starting mid-piece keeps the input applied at its start.
    assert _pieces(line, 0.12, 0.27) == [(0.03, 1.0), (0.05, 2.0), (0.07, 3.0)]


def test_pieces_cover_the_interval_exactly() -> None:
    line = _line(0.075)
    pieces = line.segments(0.01, 0.33)
    assert sum(d for d, _ in pieces) == pytest.approx(0.32, abs=1e-12)
    assert all(d > 0.0 for d, _ in pieces)


def test_forgetting_old_commands_changes_no_later_answer() -> None:
    line, kept = _line(0.1), _line(0.1)
    line.forget_before(0.17)
    for start in (0.17, 0.2, 0.25):
        assert _pieces(line, start, start + 0.2) == _pieces(kept, start, start + 0.2)
    assert line.last_issued()[0] == 3.0


def test_reset_and_bad_input() -> None:
    line = _line(0.1)
    line.reset(np.array([7.0]))
    assert line.applied_at(1.0)[0] == 7.0 and line.last_issued()[0] == 7.0
    with pytest.raises(ConfigError, match="delay_s = -0.1"):
        IssuedInputs(-0.1, np.zeros(1))
    line.record(1.0, np.array([1.0]))
    with pytest.raises(ValueError, match="t_s = 0.5"):
        line.record(0.5, np.array([1.0]))
