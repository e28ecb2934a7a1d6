"""``cosim inspect``: a log's channels, configuration, versions, warnings and metrics."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from cosim.cli.common import Handler, format_value, print_table
from cosim.core.exceptions import CosimError


def add_parsers(commands: Any) -> dict[str, Handler]:
    inspect = commands.add_parser("inspect", help="summarise an MCAP log")
    inspect.add_argument("file", metavar="FILE.mcap")
    inspect.add_argument("--json", action="store_true", help="print one JSON object")
    inspect.add_argument("--topic", metavar="T", help="print this topic's messages (JSON lines)")
    inspect.add_argument("--head", type=int, metavar="N", help="only the first N messages")
    inspect.add_argument("--csv", metavar="DIR",
                         help="write each topic (or only --topic) as DIR/<topic>.csv")
    inspect.add_argument("--require", action="append", default=[], metavar="'STL FORMULA'",
                         help="evaluate this STL requirement on the log's signals and print "
                         "its robustness (repeatable; exit 3 when one is violated), e.g. "
                         "'always (abs(cte_m) <= 0.3)'")
    return {"inspect": command}


def command(args: argparse.Namespace) -> int:
    from cosim.log.export import csv_command, log_warnings
    from cosim.log.reader import log_file_problem, read_summary
    from cosim.simulation.beliefs import mismatch_table, told
    from cosim.simulation.changes import config_changes

    path = Path(args.file)
    problem = log_file_problem(path)
    if problem is not None:
        raise CosimError(f"{args.file!r}: {problem} (expected an MCAP log)")
    period_s = _log_period_s(args.require, path)
    summary = read_summary(path)
    if args.require:
        return _requirements(path, args.require, period_s, args.json)
    if args.csv is not None:
        return csv_command(summary, args.csv, args.topic, args.head)
    if args.topic is not None:
        return _print_topic(path, summary, args.topic, args.head)
    document = {
        "file": str(path),
        "truncated": summary.truncated,
        "duration_s": summary.duration_s,
        "message_count": summary.message_count,
        "channels": [
            {"topic": c.topic, "schema": c.schema_name, "schema_encoding": c.schema_encoding,
             "message_encoding": c.message_encoding, "count": c.message_count}
            for c in sorted(summary.channels, key=lambda c: c.topic)
        ],
        "attachments": summary.attachments,
        "versions": summary.versions,
        "config": summary.config,
        "changes": config_changes(summary.config) if summary.config else [],
        "mismatch": [row.as_dict() for row in mismatch_table(summary.config or {})],
        "beliefs_from_plant": told(summary.config or {}),
        "metrics": summary.metrics or {},
        "warnings": log_warnings(summary),
    }
    if args.json:
        print(json.dumps(document))
        return 0
    _print_summary(path, summary, document)
    return 0


def _print_topic(path: Path, summary: Any, topic: str, head: int | None) -> int:
    """One topic's messages as JSON lines (the first ``head`` only, if given)."""
    from cosim.log.reader import iter_messages

    topics = [c.topic for c in summary.channels]
    if topic not in topics:
        raise CosimError(f"--topic {topic!r}: expected one of "
                         f"{', '.join(topics) or '(none: the log has no channels)'}")
    if head is not None and head < 0:
        raise CosimError(f"--head {head}: expected a count >= 0")
    for n, (log_time_ns, message) in enumerate(iter_messages(path, topic)):
        if head is not None and n >= head:
            break
        print(json.dumps({"log_time_ns": log_time_ns, **message}))
    return 0


def _print_summary(path: Path, summary: Any, document: dict[str, Any]) -> None:
    from cosim.simulation.beliefs import mismatch_line
    from cosim.simulation.changes import base_scenario, changes_text

    print(f"{path}  {summary.duration_s:.3f} s  {summary.message_count} messages"
          + ("  (TRUNCATED: read up to the last complete record)" if summary.truncated else ""))
    if summary.metrics:
        print(f"outcome {summary.metrics.get('outcome', 'n/a (logged before outcomes)')}  "
              f"completed {format_value(summary.metrics.get('completed'))}")
    width = max((len(c["topic"]) for c in document["channels"]), default=0)
    for channel in document["channels"]:
        print(f"  {channel['topic']:<{width}}  {channel['count']:>7}  {channel['schema']}")
    config = summary.config
    if config:
        print(f"scenario {config.get('name')}  seed {config.get('seed')}  tracker "
              f"{config.get('tracker', {}).get('name')}  estimator "
              f"{config.get('estimator', {}).get('name')}")
        print(f"changed from {base_scenario(config)}: "
              f"{changes_text(document['changes'], at_most=12)}")
        print(mismatch_line(config))
    if summary.versions:
        print("versions " + "  ".join(f"{k} {v}" for k, v in summary.versions.items()))
    for warning in document["warnings"]:
        print(f"WARNING: {warning}")
    if summary.metrics:
        print_table("metrics", [(k, format_value(v)) for k, v in summary.metrics.items()])
    elif summary.written_by_cosim:
        print("metrics: none (the run did not finish)")


def _log_period_s(formulas: list[str], path: Path) -> float:
    """The log period of ``path`` (the sampling period of its signals), after checking every
    formula before the log is read (a typo costs no reading)."""
    from cosim.log.reader import read_summary
    from cosim.simulation.requirements import check_formula

    for formula in formulas:
        check_formula(formula, "--require")
    if not formulas:
        return 0.0
    config = read_summary(path).config or {}
    return float(config.get("sim", {}).get("log_period_s", 0.01))


def _requirements(path: Path, formulas: list[str], period_s: float, as_json: bool) -> int:
    """Each formula's robustness on the log's ``/control/errors`` and ``/vehicle/truth``
    (the signals the run itself evaluates): 0 when every one holds, else 3."""
    from cosim.cli.common import EXIT_BAD_OUTCOME
    from cosim.log import topics
    from cosim.log.reader import iter_messages
    from cosim.simulation.requirements import robustness, trace_from_messages

    errors = [m for _, m in iter_messages(path, topics.CONTROL_ERRORS)]
    truths = [m for _, m in iter_messages(path, topics.VEHICLE_TRUTH)]
    if not errors:
        raise CosimError(f"{str(path)!r}: no {topics.CONTROL_ERRORS} messages: expected a "
                         "log of a path-tracking run")
    trace = trace_from_messages(errors, truths)
    rows = [{"formula": f, "robustness": robustness(f, trace, period_s)} for f in formulas]
    for row in rows:
        row["satisfied"] = bool(row["robustness"] >= 0.0)
    if as_json:
        print(json.dumps({"file": str(path), "requirements": rows}))
    else:
        for row in rows:
            verdict = "holds" if row["satisfied"] else "VIOLATED"
            print(f"{verdict}  robustness {row['robustness']:.6g}  {row['formula']}")
    return 0 if all(row["satisfied"] for row in rows) else EXIT_BAD_OUTCOME
