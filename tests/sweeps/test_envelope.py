"""``cosim envelope``: the search on robustness functions whose zeros are known, then on the
lane change as a user runs it."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from cosim.sweeps.envelope import search
from cosim.sweeps.envelope_search import Bracket, ensemble_boundary
from cosim.sweeps.envelope_spec import EnvelopeSpec, SearchParameter

COSIM = str(Path(sys.executable).with_name("cosim"))


def spec_of(*parameters: SearchParameter, seeds: int = 4, resolution: float = 0.005,
            failure_rate: float = 0.1) -> EnvelopeSpec:
    return EnvelopeSpec(
        name="synthetic", description="", scenario="lane-change", tracker=None,
        estimator=None, duration_s=None, seeds=tuple(range(seeds)), fixed=(),
        requirement="always (abs(cte_m) <= 0.3)", parameters=parameters,
        failure_rate=failure_rate, resolution=resolution, max_rays=17, ray_address=None,
        tracker_name="t", estimator_name="e")


MASS = SearchParameter("plant.mass_kg", 1575.0, 3500.0, "tracker.model.mass_kg", 1575.0)
FRICTION = SearchParameter("plant.tyre_friction", 1.0, 0.3, "tracker.model.tyre_friction",
                           1.0)


def evaluator(robustness: Any, calls: list[int]) -> Any:
    """Rows as runs give them, from ``robustness(values, seed)`` (NaN: the run spun)."""
    def evaluate(keys: list[tuple[tuple[float, ...], int]]) -> dict:
        calls.append(len(keys))
        rows = {}
        for values, seed in keys:
            r = robustness(values, seed)
            outcome = "spun" if math.isnan(r) else "ok"
            rows[(values, seed)] = {"error": "", "metrics": {"stl_robustness": r,
                                                              "outcome": outcome}}
        return rows
    return evaluate


def test_one_parameter_finds_each_seeds_zero_to_the_resolution() -> None:
    """Robustness falls with mass, each seed crossing zero at its own mass (a curved
    function, not a line): every seed's critical mass within 0.5 % of 1575 kg."""
    zeros = {0: 2300.0, 1: 2410.0, 2: 2205.0, 3: 2660.0}

    def robustness(values: tuple[float, ...], seed: int) -> float:
        return 0.3 * (1.0 - (values[0] / zeros[seed]) ** 3)

    calls: list[int] = []
    spec = spec_of(MASS)
    (ray,), rows = search(spec, evaluator(robustness, calls))
    for seed, bracket in ray.brackets.items():
        assert abs(MASS.value(bracket.critical_s) - zeros[seed]) <= 0.005 * 1575.0, seed
    # The boundary where more than 10 % of 4 seeds fail: the first seed to fail.
    assert ensemble_boundary(ray.critical_shares(), 0.1) == min(ray.critical_shares())
    assert len(rows) <= 4 * 10  # regula falsi: far fewer than a 0.5 % grid's 244 a seed


def test_a_run_that_stops_counts_as_a_failure_without_a_value() -> None:
    """Beyond 2500 kg every run spins (no robustness): bisection brackets the step."""
    def robustness(values: tuple[float, ...], seed: int) -> float:
        return math.nan if values[0] > 2500.0 + 10 * seed else 0.2

    calls: list[int] = []
    (ray,), _ = search(spec_of(MASS), evaluator(robustness, calls))
    for seed, bracket in ray.brackets.items():
        assert abs(MASS.value(bracket.critical_s) - (2500.0 + 10 * seed)) <= 0.005 * 1575.0


def test_nominal_failure_and_a_requirement_that_always_holds() -> None:
    calls: list[int] = []
    (ray,), rows = search(spec_of(MASS), evaluator(lambda v, s: 0.1, calls))
    assert all(math.isinf(s) for s in ray.critical_shares()) and len(rows) == 8
    (ray,), rows = search(spec_of(MASS), evaluator(lambda v, s: -0.1, calls))
    assert ray.critical_shares() == [0.0] * 4 and len(rows) == 4


def test_two_parameters_trace_a_curved_boundary() -> None:
    """The requirement fails outside a quarter circle of radius 0.6 in the box (a share of
    the way to each limit); every ray's boundary lies on it to the resolution, and rays
    are added until neighbouring boundary points are close."""
    def robustness(values: tuple[float, ...], seed: int) -> float:
        u = (MASS.share(values[0]), FRICTION.share(values[1]))
        return 0.6 + 0.01 * seed - math.hypot(*u)

    calls: list[int] = []
    spec = spec_of(MASS, FRICTION, seeds=2)
    rays, rows = search(spec, evaluator(robustness, calls))
    assert len(rays) > 5  # refined beyond the first five
    for item in rays:
        point = item.ray.unit_point(ensemble_boundary(item.critical_shares(), 0.1))
        assert abs(math.hypot(*point) - 0.6) < 0.01, item.ray.angle_deg
    angles = sorted(r.ray.angle_deg for r in rays)
    assert angles[0] == 0.0 and angles[-1] == 90.0


def test_illinois_keeps_moving_a_stuck_end() -> None:
    """A convex robustness keeps plain regula falsi's steps on one side; the Illinois
    modification halves the kept end's weight, so the bracket closes in fewer steps (10
    against 13 for this cubic; the step kept inside the bracket's middle bounds both)."""
    bracket = Bracket(resolution=1e-4)
    steps = 0
    while (s := bracket.next_s()) is not None:
        score = 1.0 - (s / 0.6) ** 3
        bracket.record(s, score, score >= 0.0)
        steps += 1
    assert abs(bracket.critical_s - 0.6) < 1e-4 and steps <= 11


@pytest.mark.slow
def test_the_envelope_of_a_short_lane_change(tmp_path: Path) -> None:
    """As a user runs it: one parameter, two seeds; the boundary is real (a run just inside
    passes, one just outside fails for the seed that fails first), the answer is in words,
    and --resume runs nothing again. The ray ends at 3500 kg, where both seeds miss the
    requirement by 52 mm and more (at 2800 kg, since the controller's tyres saturate,
    ``tracker.grip.saturating_tyres``, seed 1 holds it, 73.7 mm: a ray that ends where a
    seed never fails finds it no critical time)."""
    spec = tmp_path / "spec.yaml"
    spec.write_text("scenario: lane-change\nduration_s: 6\nseeds: 2\n"
                    "requirement: always (abs(cte_m) <= 0.08)\n"
                    "parameters: {plant.mass_kg: 3500}\nresolution: 0.01\n")
    out = tmp_path / "out"
    done = subprocess.run([COSIM, "envelope", str(spec), "--out", str(out), "--workers", "2"],
                          capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0, done.stderr
    assert "`plant.mass_kg` may be up to " in done.stdout
    assert "`tracker.model.mass_kg` = 1575" in done.stdout
    document = json.loads((out / "envelope.json").read_text())
    (ray,) = document["rays"]
    boundary = ray["boundary"][0]
    assert boundary is not None and 1575.0 < boundary < 3500.0
    first = min(ray["seeds"], key=lambda seed: ray["seeds"][seed]["critical_s"])
    for mass, holds in ((boundary - 0.01 * 1575.0, True), (boundary + 0.01 * 1575.0, False)):
        run = subprocess.run([COSIM, "run", "lane-change", "--duration", "6", "--seed", first,
                              "--set", f"plant.mass_kg={mass}", "--out",
                              str(tmp_path / f"check-{mass}.mcap"), "--json",
                              "--require", "always (abs(cte_m) <= 0.08)"],
                             capture_output=True, text=True, timeout=600)
        assert (run.returncode == 0) == holds, (mass, run.stderr)
    again = subprocess.run([COSIM, "envelope", str(spec), "--out", str(out), "--resume"],
                           capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert f"envelope: {document['runs']} runs (0 now)" in again.stdout
    assert (out / "envelope.png").stat().st_size > 10_000


@pytest.mark.parametrize(("body", "fragment"), [
    ("parameters: {plant.mass_kg: 3000}\n", "requirement = None: expected an STL formula"),
    ("requirement: always (abs(cte) <= 0.3)\nparameters: {plant.mass_kg: 3000}\n",
     "unknown signal 'cte'"),
    ("requirement: always (abs(cte_m) <= 0.3)\nparameters: {plant.mas_kg: 3000}\n",
     "parameters: 'plant.mas_kg': unknown dotted path"),
    ("requirement: always (abs(cte_m) <= 0.3)\nparameters: {plant.mass_kg: 1575}\n",
     "expected a search limit, a number other than the nominal 1575"),
    ("requirement: always (abs(cte_m) <= 0.3)\nparameters: {plant.mass_kg: 3000, "
     "plant.tyre_friction: 0.3, plant.cog_height_m: 0.7}\n", "3 given: expected one or two"),
    ("requirement: always (abs(cte_m) <= 0.3)\nparameters: {plant.mass_kg: 3000}\n"
     "failure_rate: 1.5\n", "failure_rate: 1.5: expected a share in [0, 1)"),
    ("requirement: always (abs(cte_m) <= 0.3)\nparameters: {tracker.name: 3}\n",
     "is no number"),
])
def test_a_bad_envelope_spec_is_one_line(body: str, fragment: str, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    from cosim.cli import main

    spec = tmp_path / "spec.yaml"
    spec.write_text("scenario: lane-change\nseeds: 2\n" + body)
    assert main(["envelope", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0], err
    assert not (tmp_path / "out").exists()


def test_a_spec_of_the_other_kind_names_the_command(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    from cosim.cli import main

    examples = Path(__file__).resolve().parents[2] / "examples"
    assert main(["sweep", str(examples / "envelope-mass-friction.yaml"), "--out",
                 str(tmp_path / "a")]) == 2
    assert "(an envelope spec? run `cosim envelope` on it)" in capsys.readouterr().err
    assert main(["envelope", str(examples / "mass-friction.yaml"), "--out",
                 str(tmp_path / "b")]) == 2
    assert "(a sweep spec? run `cosim sweep` on it)" in capsys.readouterr().err
