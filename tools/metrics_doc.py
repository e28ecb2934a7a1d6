"""Write ``docs/metrics.md`` and ``docs/topics.md`` from their registries.

The metric keys are declared in :mod:`cosim.simulation.metric_keys`, the log's topics in
:mod:`cosim.log.topics`. Run ``python tools/metrics_doc.py`` after adding or changing one;
a test fails while a file differs from what this writes.
"""

from __future__ import annotations

from pathlib import Path

from cosim.log import topics
from cosim.simulation import metric_keys

DOCS = Path(__file__).resolve().parent.parent / "docs"


def main() -> None:
    for name, text in (("metrics.md", metric_keys.markdown()),
                       ("topics.md", topics.markdown())):
        path = DOCS / name
        path.write_text(text, encoding="utf-8")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
