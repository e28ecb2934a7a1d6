"""Each state's error over the filter's variance of it, over an ensemble
(:func:`cosim.sweeps.ensemble.state_consistency`)."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.sweeps.ensemble import EnsembleMember, state_consistency


def _members(sigma_true: dict[str, float], sigma_believed: dict[str, float], runs: int = 50,
             seed: int = 3) -> list[EnsembleMember]:
    """Runs of 5 s at 100 Hz whose errors are drawn with ``sigma_true`` while the filter
    believes ``sigma_believed`` (the second half of the runs for ``late`` twice as large)."""
    rng = np.random.default_rng(seed)
    t_s = np.arange(0.0, 5.0, 0.01)
    members = []
    for run in range(runs):
        normalized = {}
        for name, sigma in sigma_true.items():
            scale = np.where(t_s >= 3.0, 2.0, 1.0) if name == "late" else 1.0
            error = rng.normal(0.0, sigma, t_s.size) * scale
            normalized[name] = (error / sigma_believed[name]) ** 2
        members.append(EnsembleMember(seed=run, t_s=t_s, nees=np.full(t_s.size, 4.0),
                                      nis_sum={}, nis_dof={}, metrics={},
                                      normalized_errors=normalized))
    return members


def test_each_state_says_how_its_variance_stands_to_its_error() -> None:
    """A state believed right gives 1, one believed with twice the error's sigma 1/4, one
    with half of it 4; the windows show where a state's error grows (x4 after 3 s)."""
    members = _members({"right": 0.1, "wide": 0.1, "narrow": 0.1, "late": 0.1},
                       {"right": 0.1, "wide": 0.2, "narrow": 0.05, "late": 0.1})
    figures = {f.state: f for f in state_consistency(members)}
    assert figures["right"].mean == pytest.approx(1.0, rel=0.03)
    assert figures["wide"].mean == pytest.approx(0.25, rel=0.03)
    assert figures["narrow"].mean == pytest.approx(4.0, rel=0.03)
    late = figures["late"].windows
    assert [start for start, _ in late] == [1.0, 2.0, 3.0, 4.0]
    assert late[0][1] == pytest.approx(1.0, rel=0.1) and late[1][1] == pytest.approx(1.0, rel=0.1)
    assert late[2][1] == pytest.approx(4.0, rel=0.1) and late[3][1] == pytest.approx(4.0, rel=0.1)
    # The settling time is left out: the mean is over 1-5 s (a quarter at 1, three at 4...).
    assert figures["late"].mean == pytest.approx((2 * 1.0 + 2 * 4.0) / 4, rel=0.05)


def test_a_state_some_runs_lack_is_left_out() -> None:
    members = _members({"x": 0.1, "y": 0.1}, {"x": 0.1, "y": 0.1})
    members[0] = EnsembleMember(seed=0, t_s=members[0].t_s, nees=members[0].nees, nis_sum={},
                                nis_dof={}, metrics={},
                                normalized_errors={"x": members[0].normalized_errors["x"]})
    assert [f.state for f in state_consistency(members)] == ["x"]
    with pytest.raises(ValueError):
        state_consistency([])
