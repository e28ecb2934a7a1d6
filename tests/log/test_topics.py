"""The log's topics come from one table (:mod:`cosim.log.topics`).

Every channel of a real run is a row of the table with the table's schema; no module other
than the table spells a topic's name; ``docs/topics.md`` is what the table generates.
"""

from __future__ import annotations

import ast
from pathlib import Path

from mcap.reader import make_reader

from cosim.log import topics
from cosim.simulation.runner import RunResult

ROOT = Path(__file__).resolve().parents[2]
NAMES = {topic.name for topic in topics.TOPICS}


def test_docs_topics_md_is_generated_from_the_table() -> None:
    assert (ROOT / "docs" / "topics.md").read_text(encoding="utf-8") == topics.markdown(), \
        "docs/topics.md is stale: run python tools/metrics_doc.py"


def test_every_channel_of_a_run_is_in_the_table(short_run: RunResult) -> None:
    with open(short_run.log_path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        assert schema.name == topics.schema_of(channel.topic)["title"], channel.topic
    logged = {c.topic for c in summary.channels.values()}
    assert {topics.VEHICLE_TRUTH, topics.METRICS, topics.sensor_topic("gnss")} <= logged


def topic_literals(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every string constant in ``path`` that is a topic's name."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str)
            and (node.value in NAMES or node.value.startswith(topics.SENSORS_PREFIX))]


def test_no_module_but_the_table_spells_a_topic() -> None:
    table = ROOT / "cosim" / "log" / "topics.py"
    found = [f"{path.relative_to(ROOT)}:{line}: {text}"
             for package in ("cosim", "tracker", "estimation")
             for path in sorted((ROOT / package).rglob("*.py")) if path != table
             for line, text in topic_literals(path)]
    assert not found, "\n".join(found)


def test_the_literal_check_sees_a_topic(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text('WRITE = "/vehicle/truth"\nSENSOR = f"/sensors/{name}"\n')
    assert [text for _, text in topic_literals(bad)] == ["/vehicle/truth", "/sensors/"]
