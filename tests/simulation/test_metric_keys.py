"""The metric-key registry is complete and ``docs/metrics.md`` is what it generates.

Real runs of each kind (path tracking, ACC with traffic, a circuit, ISO gates, an open-loop
manoeuvre) emit only keys the registry declares, each listed in ``docs/metrics.md`` with
its unit and meaning.
"""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

from cosim.simulation.metric_keys import (
    METRIC_KEYS,
    METRICS,
    PLACEHOLDERS,
    WALL_CLOCK_KEYS,
    markdown,
    metric_key,
    undocumented,
)
from cosim.simulation.runner import RunResult
from tests.conftest import run_scenario

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "metrics.md"


def test_docs_metrics_md_is_generated_from_the_registry() -> None:
    assert DOC.read_text(encoding="utf-8") == markdown(), \
        "docs/metrics.md is stale: run python tools/metrics_doc.py"


def test_an_undocumented_key_is_found() -> None:
    """The check the run tests rely on is not vacuous: a made-up key, a family member with a
    value its placeholder does not take, and a typo are all undocumented."""
    assert undocumented(["cte_max_m", "nis_gnss", "gate_3_passed", "spun_t_s",
                         "acc_k_vrel_drift_pct", "lap_12_cte_max_m"]) == []
    assert undocumented(["made_up_m", "nis_radar", "gate_x_passed", "cte_max", "nis_",
                         "lap_0_time_s"]) == [
        "cte_max", "gate_x_passed", "lap_0_time_s", "made_up_m", "nis_", "nis_radar"]


def test_the_contract_keys_are_the_rows_marked_contract() -> None:
    assert {key.name for key in METRICS if key.contract} == set(METRIC_KEYS)
    assert len(set(METRIC_KEYS)) == len(METRIC_KEYS) == 24
    assert set(WALL_CLOCK_KEYS) - set(METRIC_KEYS) == {"setup_time_s"}  # timing, not contract


def test_every_row_is_declared_once_and_its_emitter_exists() -> None:
    names = [key.name for key in METRICS]
    assert len(names) == len(set(names))
    for key in METRICS:
        importlib.import_module(key.emitter)
        assert key.meaning and key.unit
    for placeholder in PLACEHOLDERS:
        assert any(f"<{placeholder}>" in key.name for key in METRICS), placeholder


RUNS = {
    "lane-change": ("lane-change", 1.0, ()),
    "acc": ("acc-cut-in", 1.0, ()),
    "track": ("track", 1.0, ()),
    "iso-gates": ("iso-lane-change", 0.5, ()),
    "step-steer": ("step-steer", 1.0, ()),
}


@pytest.fixture(scope="module", params=sorted(RUNS))
def kind_of_run(request: pytest.FixtureRequest,
                tmp_path_factory: pytest.TempPathFactory) -> tuple[str, RunResult]:
    scenario, duration_s, overrides = RUNS[request.param]
    return request.param, run_scenario(tmp_path_factory.mktemp(request.param), scenario,
                                       *overrides, duration_s=duration_s)


def test_every_key_a_run_emits_is_documented(kind_of_run: tuple[str, RunResult]) -> None:
    kind, result = kind_of_run
    assert undocumented(result.metrics) == [], f"{kind} emits keys metric_keys lacks"
    doc = DOC.read_text(encoding="utf-8")
    for key in result.metrics:
        row = metric_key(key)
        assert f"| `{row.name}`" in doc, key
        assert row.unit in {"bool", "text"} or not isinstance(result.metrics[key], str)


def test_each_kind_of_run_has_its_own_keys(kind_of_run: tuple[str, RunResult]) -> None:
    """The runs above cover every scope: each has the keys that only its kind emits."""
    kind, result = kind_of_run
    expected = {"lane-change": "nis_gnss", "acc": "acc_k_v", "track": "track_limit_exceedances",
                "iso-gates": "gate_1_passed", "step-steer": "steady_yaw_rate_radps"}[kind]
    assert expected in result.metrics
    assert set(METRIC_KEYS) <= set(result.metrics)
