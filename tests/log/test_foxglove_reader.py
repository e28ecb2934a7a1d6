"""A second MCAP reader, Foxglove's TypeScript @mcap/core, reads cosim's logs.

Runs when node and npm are on the machine (CI has them); the packages come from the npm
registry into tests/js/node_modules (git-ignored) on the first run.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from cosim.log.reader import read_summary
from cosim.simulation.runner import RunResult

JS_DIR = Path(__file__).resolve().parents[1] / "js"

pytestmark = pytest.mark.skipif(
    shutil.which("node") is None or shutil.which("npm") is None,
    reason="node and npm are needed for Foxglove's TypeScript MCAP reader",
)


INSTALL_TIMEOUT_S = 60.0
"""How long one ``npm install`` may take (the five packages take about a second). Once, in
a fresh clone, npm stayed in its epoll wait after every package was in place and its log
said nothing more, until the old 600 s limit."""


@pytest.fixture(scope="module")
def node_reader() -> Path:
    installed = JS_DIR / "node_modules" / "@mcap" / "core" / "package.json"
    for _ in range(2):
        if installed.is_file():
            break
        try:
            subprocess.run(["npm", "install", "--no-audit", "--no-fund", "--silent"],
                           cwd=JS_DIR, check=True, capture_output=True,
                           timeout=INSTALL_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            continue  # npm is stopped; what it placed is checked, then it is asked again
    assert installed.is_file(), "npm did not install @mcap/core into tests/js/node_modules"
    return JS_DIR / "read_mcap.mjs"


def test_typescript_reader_finds_every_channel_and_schema(node_reader: Path,
                                                          short_run: RunResult) -> None:
    result = subprocess.run(["node", str(node_reader), str(short_run.log_path)],
                            capture_output=True, text=True, check=False, timeout=300)
    assert result.returncode == 0, result.stderr
    document = json.loads(result.stdout)
    ours = {c.topic: c for c in read_summary(short_run.log_path).channels}
    theirs = {c["topic"]: c for c in document["channels"]}
    assert set(theirs) == set(ours)
    for topic, channel in theirs.items():
        assert channel["schemaName"] == ours[topic].schema_name, topic
        assert channel["schemaEncoding"] == "jsonschema"
        assert channel["count"] == ours[topic].message_count, topic
    assert document["parsed"] == sum(c.message_count for c in ours.values())
    assert {"run", "metrics"} <= set(document["metadata"])
    assert document["attachments"] == ["sedan.xml"]
