"""YAML as a user means it (exponent floats, unique keys, bounded echoes), constant-memory
run statistics, and the closed circuit path."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from cosim.core.config_fields import to_dict
from cosim.core.exceptions import ConfigError
from cosim.core.yaml_io import SHOWN_CHARS, dumps, loads, shown
from cosim.simulation.running_stats import RunningStats, SampleBlock, Samples
from cosim.simulation.scenario_config import load_config
from cosim.sweeps.spec import load_spec
from tracker.paths.reference_path import ReferencePath


@pytest.mark.parametrize(("text", "value"), [
    ("2e3", 2000.0), ("1e-5", 1e-5), ("-1.5E+2", -150.0), (".5", 0.5), ("3", 3), ("1_0", 10),
    ("0x10", 16), (".inf", math.inf), ("1e", "1e"), ("e5", "e5"), ("2024-01-02", None),
])
def test_yaml_1_2_floats(text: str, value: object) -> None:
    parsed = loads(f"v: {text}")["v"]
    if value is None:  # a date stays a date
        assert not isinstance(parsed, (int, float, str))
        return
    assert parsed == value and type(parsed) is type(value)


def test_exponents_reach_the_config_from_set_file_and_sweep(tmp_path) -> None:  # noqa: ANN001
    config_file = tmp_path / "c.yaml"
    config_file.write_text("sensors:\n  gnss:\n    sigma_m: 5e-2\n")
    config = load_config("lane-change", str(config_file), ["plant.mass_kg=1.7e3"])
    assert config.plant.mass_kg == 1700.0 and config.sensors.gnss.sigma_m == 0.05
    spec = tmp_path / "s.yaml"
    spec.write_text("scenario: lane-change\ngrid:\n  plant.mass_kg: [1.5e3, 2e3]\n")
    assert load_spec(spec).parameters[0].values == (1500.0, 2000.0)


def test_a_duplicate_key_names_itself_and_its_line() -> None:
    with pytest.raises(ConfigError, match=r"line 3: key 'b' given twice"):
        loads("a: 1\nb: 2\nb: 3\n")
    assert loads("a: {b: 1}\nc: {b: 2}\n") == {"a": {"b": 1}, "c": {"b": 2}}


@pytest.mark.parametrize("scenario", ["lane-change", "acc-cut-in", "track"])
def test_dumped_yaml_is_pyyamls_text_and_reads_back(scenario: str) -> None:
    # A run's configuration as its log keeps it: PyYAML's pure-Python text to the byte (the
    # emitter may be libyaml's), numbers such as 1e-05 as YAML 1.2 floats again.
    data = to_dict(load_config(scenario))
    text = dumps(data)
    assert text == yaml.safe_dump(data, sort_keys=False)
    assert loads(text) == data


def test_shown_values_are_bounded() -> None:
    huge = [[list(range(1000))] * 1000] * 1000
    assert len(shown(huge)) <= SHOWN_CHARS
    assert len(shown("x" * 10**6)) <= SHOWN_CHARS
    assert shown(1500.0) == "1500.0" and shown("abc") == "'abc'"


def test_running_stats_match_numpy() -> None:
    values = np.random.default_rng(1).normal(0.3, 2.0, 1001)
    stats, samples = RunningStats(), Samples()
    for value in values:
        stats.add(float(value))
        samples.add(float(value))
    stats.add(math.nan)  # left out, counted
    assert stats.count == 1001 and stats.nonfinite == 1 and math.isnan(stats.last)
    assert stats.rms == pytest.approx(np.sqrt(np.mean(values**2)), rel=1e-12)
    assert stats.mean == pytest.approx(np.mean(values), rel=1e-12)
    assert stats.max_abs == np.max(np.abs(values))
    assert (stats.minimum, stats.maximum) == (values.min(), values.max())
    assert np.array_equal(samples.as_array(), values)
    assert math.isnan(RunningStats().rms) and math.isnan(RunningStats().max_abs)


def test_a_sample_block_reduces_every_row_in_fixed_groups() -> None:
    # Two columns over 2.5 blocks, a NaN among them: the same figures as adding sample by
    # sample (to the rounding of numpy's pairwise sums); reading the pending rows at any
    # moment changes nothing, bit for bit (a logged run reads them for its live metrics).
    values = np.random.default_rng(2).normal(0.1, 1.5, (250, 2))
    values[77, 1] = math.nan
    one_by_one = [RunningStats(), RunningStats()]
    for row in values:
        for stats, value in zip(one_by_one, row, strict=True):
            stats.add(float(value))

    def blocked(read_every: int) -> list[RunningStats]:
        merged = [RunningStats(), RunningStats()]

        def reduce(rows: np.ndarray) -> None:
            for column, stats in enumerate(merged):
                stats.merge(rows[:, column])

        block = SampleBlock(2, reduce, rows=100)
        for k, row in enumerate(values):
            block.add(row)
            if k % read_every == 0:
                block.pending().sum()
        block.flush()
        return merged

    for stats, reference in zip(blocked(7), one_by_one, strict=True):
        assert (stats.count, stats.nonfinite) == (reference.count, reference.nonfinite)
        assert stats.rms == pytest.approx(reference.rms, rel=1e-13)
        assert stats.mean == pytest.approx(reference.mean, rel=1e-13)
        assert (stats.low, stats.high, stats.last) == (reference.low, reference.high,
                                                        reference.last)
    assert blocked(7) == blocked(1)


def test_a_closed_circuit_wraps_its_arc_length() -> None:
    radius_m = 50.0
    angle = np.arange(0.0, 2.0 * np.pi, 1.0 / radius_m)
    path = ReferencePath(radius_m * np.sin(angle), radius_m * (1.0 - np.cos(angle)), 10.0,
                         closed=True)
    assert path.length_m == pytest.approx(2.0 * np.pi * radius_m, rel=1e-4)
    lap = path.length_m
    for s_m in (1.0, lap - 1.0):
        here = path.point(s_m)
        assert path.point(s_m + 3 * lap).x_m == pytest.approx(here.x_m, abs=1e-9)
        # A point 0.5 m outside the circle, near the seam: projected onto the right place.
        outside = path.project(here.x_m + 0.5 * np.sin(here.yaw_rad),
                               here.y_m - 0.5 * np.cos(here.yaw_rad))
        assert outside.s_m == pytest.approx(s_m, abs=1e-3)
        assert outside.lateral_error_m == pytest.approx(-0.5, abs=1e-3)
        assert here.curvature_1pm == pytest.approx(1.0 / radius_m, rel=1e-3)
