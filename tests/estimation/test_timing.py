"""The estimators' clock: same instants within float round-off, never backwards."""

from __future__ import annotations

import pytest

from estimation.errors import TimeOrderError
from estimation.timing import forward_interval_s, is_stale


def test_an_hour_of_summed_physics_steps_is_the_runners_instant() -> None:
    # MuJoCo's time is a float sum of 2 ms steps, the runner's k * 2 ms; they drift apart
    # by about 1e-9 s in six minutes (a one-hour run stopped at 361.95 s on exactly this).
    summed, steps = 0.0, 0
    while steps < 1_800_000:  # an hour
        summed += 0.002
        steps += 1
        if steps % 180_975 == 0:  # 361.95 s and its multiples
            product = steps * 0.002
            assert summed != product  # the two clocks do differ
            assert forward_interval_s(summed, product, "filter") == 0.0
            assert forward_interval_s(product, summed, "filter") == 0.0
            assert not is_stale(summed, product)
    assert forward_interval_s(361.95000000100015, 361.95, "filter") == 0.0


def test_a_step_back_is_refused_and_a_step_forward_measured() -> None:
    with pytest.raises(TimeOrderError, match="cannot go back in time"):
        forward_interval_s(3600.0, 3600.0 - 1e-4, "filter")
    assert is_stale(3600.0, 3600.0 - 1e-4)
    assert forward_interval_s(3600.0, 3600.0 + 1e-4, "filter") == pytest.approx(1e-4)
