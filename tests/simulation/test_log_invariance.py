"""Logging observes the loop and never changes it: the truth is bit-identical whatever the
log and scene rates (``sim.log_period_s``, ``sim.scene_period_s``).

Two ways the log once reached the physics: the estimate fetched for the log set the speed
the low-level layer converted the next command with, and predicting the filter to the log
instants changed how its predictions were split into sub-steps (so every later estimate,
command and state). Log instants that fall between the sensors' and the controller's
(6 ms against 10 ms and 50 ms) expose both; an actuator delay puts the command's conversion
between control instants.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.log.reader import iter_messages
from tests.conftest import run_scenario

RATES = (("0.01", "0.04"), ("0.006", "0.03"))
"""(log period, scene period) pairs [s]: the default, and one off the sensors' instants."""


def _truth(path: Path) -> dict[int, dict[str, object]]:
    return {t_ns: message for t_ns, message in iter_messages(path, "/vehicle/truth")}


@pytest.mark.parametrize("delay_s", ["0", "0.03"])
@pytest.mark.slow
def test_the_truth_does_not_depend_on_the_log_rate(tmp_path: Path, delay_s: str) -> None:
    truths = []
    for i, (log_s, scene_s) in enumerate(RATES):
        result = run_scenario(tmp_path / str(i), "lane-change",
                              f"sim.log_period_s={log_s}", f"sim.scene_period_s={scene_s}",
                              f"plant.actuator_delay_s={delay_s}", duration_s=1.5)
        assert result.completed
        truths.append(_truth(result.log_path))
    shared = sorted(set(truths[0]) & set(truths[1]))
    assert len(shared) >= 40  # every 30 ms over 1.5 s
    for t_ns in shared:
        assert truths[0][t_ns] == truths[1][t_ns], f"truth differs at t = {t_ns * 1e-9} s"
