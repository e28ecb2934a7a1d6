"""What `cosim inspect` adds to a log's summary: warnings, and CSV export of topics.

Warnings are one-line strings a reader should not miss: a truncated file, a run that did
not complete (with its abort reason), control steps whose solver failed or fell back (with
their statuses, counted from ``/control/plan``), measurements the estimator rejected (the
metrics' ``rejected_*`` keys and ``channels_gated``).

CSV export writes one file per topic, ``<topic without the leading slash, / -> _>.csv``
(``/vehicle/truth`` -> ``vehicle_truth.csv``), one row per message, first column
``log_time_ns``. Nested objects are flattened with dots (``translation.x``); an array whose
length is the same in every message of the topic is flattened into ``name[i]`` columns; an
array whose length varies between messages is skipped and named in
:attr:`CsvExport.skipped`. A list of names that is the same in every message
(``state_names`` of ``/vehicle/estimate``) is not repeated in every row: it names the
columns instead, ``covariance[x_m][y_m]`` (the upper triangle of the symmetric matrix) and
any vector of its length ``[x_m]``. ``null`` is an
empty cell, booleans are ``true``/``false``, floats keep full precision.
"""

from __future__ import annotations

import csv
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.core.exceptions import CosimError
from cosim.log.reader import LogSummary, iter_messages, iter_topics

PLAN_TOPIC = "/control/plan"


def _counted(counter: Counter[str]) -> str:
    return ", ".join(f"{status} x{n}" for status, n in counter.most_common())


def log_warnings(summary: LogSummary) -> list[str]:
    """One line per thing that went wrong in the run or the file (empty: nothing did)."""
    warnings: list[str] = []
    if summary.truncated:
        warnings.append("truncated file: it ends without a footer (the writer was killed?); "
                        "read up to the last complete record")
    metrics = summary.metrics
    if not summary.written_by_cosim:
        warnings.append(f"not written by cosim (writer {summary.library!r}): only its "
                        "channels and counts are shown")
    elif metrics is None:
        warnings.append("no /metrics message: the run did not finish, so there are no "
                        "metrics")
    elif metrics.get("completed") is False:
        reason = metrics.get("abort_reason") or "no reason logged"
        warnings.append(f"run did not complete (completed: false): {reason}")
    if metrics and metrics.get("outcome", "ok") != "ok":
        has_events = "/events" in {c.topic for c in summary.channels}
        warnings.append(f"run ended badly: outcome {metrics['outcome']}"
                        + (" (see /events)" if has_events else ""))
    warnings.extend(_solver_warnings(summary))
    if metrics:
        warnings.extend(_rejection_warnings(metrics))
    return warnings


def _solver_warnings(summary: LogSummary) -> list[str]:
    if PLAN_TOPIC not in {c.topic for c in summary.channels}:
        return []
    steps = 0
    fallbacks: Counter[str] = Counter()
    unsuccessful: Counter[str] = Counter()
    for _, plan in iter_messages(summary.path, PLAN_TOPIC):
        steps += 1
        status = str(plan.get("status", "?"))
        if plan.get("fallback"):
            fallbacks[status] += 1
        elif plan.get("success") is False:
            unsuccessful[status] += 1
    warnings = []
    if fallbacks:
        warnings.append(f"solver failures: {sum(fallbacks.values())} of {steps} control steps "
                        f"used a fallback ({_counted(fallbacks)})")
    if unsuccessful:
        warnings.append(f"solver: {sum(unsuccessful.values())} of {steps} control steps "
                        f"reported an unsuccessful solve but kept its plan "
                        f"({_counted(unsuccessful)})")
    return warnings


def _rejection_warnings(metrics: dict[str, Any]) -> list[str]:
    total = metrics.get("rejected_measurements")
    causes = {key.removeprefix("rejected_"): value for key, value in metrics.items()
              if key.startswith("rejected_") and key != "rejected_measurements"
              and isinstance(value, int | float) and value}
    warnings = []
    if total or causes:
        total = total if total else int(sum(causes.values()))
        detail = ", ".join(f"{cause} {value:g}" for cause, value in causes.items())
        warnings.append(f"estimator rejected {total:g} measurements"
                        + (f" ({detail})" if detail else ""))
    gated = metrics.get("channels_gated")
    if gated:
        warnings.append(f"estimator gate refused {gated:g} single measurement channels")
    return warnings


@dataclass
class CsvExport:
    """What :func:`export_csv` wrote."""

    files: dict[str, Path] = field(default_factory=dict)
    """Topic -> CSV file."""
    rows: dict[str, int] = field(default_factory=dict)
    """Topic -> data rows written."""
    skipped: dict[str, list[str]] = field(default_factory=dict)
    """Topic -> the variable-length arrays left out."""


def csv_name(topic: str) -> str:
    """``/vehicle/truth`` -> ``vehicle_truth.csv``."""
    return topic.strip("/").replace("/", "_") + ".csv"


def _array_lengths(value: Any, prefix: str, lengths: dict[str, set[int]]) -> None:
    if isinstance(value, dict):
        for key, item in value.items():
            _array_lengths(item, f"{prefix}.{key}" if prefix else key, lengths)
    elif isinstance(value, list):
        lengths.setdefault(prefix, set()).add(len(value))
        for i, item in enumerate(value):
            _array_lengths(item, f"{prefix}[{i}]", lengths)


def _flatten(value: Any, prefix: str, variable: set[str], row: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten(item, f"{prefix}.{key}" if prefix else key, variable, row)
    elif isinstance(value, list):
        if prefix in variable:
            return
        for i, item in enumerate(value):
            _flatten(item, f"{prefix}[{i}]", variable, row)
    else:
        row[prefix] = value


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _constant_names(messages: list[tuple[int, dict[str, Any]]]) -> dict[str, list[str]]:
    """Top-level lists of strings that are the same in every message (``state_names``):
    labels, written once in the header instead of in every row."""
    if not messages:
        return {}
    first = messages[0][1]
    return {key: value for key, value in first.items()
            if isinstance(value, list) and value and all(isinstance(v, str) for v in value)
            and all(message.get(key) == value for _, message in messages)}


def _named(message: dict[str, Any], labels: dict[str, list[str]]) -> dict[str, Any]:
    """``message`` without its label lists, its arrays over the one label list named by
    it: ``mean[x_m]`` for a vector of its length, ``covariance[x_m][y_m]`` (upper triangle:
    the matrix is symmetric) for a flattened square matrix."""
    if not labels:
        return message
    names = next(iter(labels.values())) if len(labels) == 1 else None
    out: dict[str, Any] = {}
    for key, value in message.items():
        if key in labels:
            continue
        if names is not None and isinstance(value, list) and value and all(
                isinstance(v, (int, float)) or v is None for v in value):
            n = len(names)
            if len(value) == n * n:
                for row in range(n):
                    for col in range(row, n):
                        out[f"{key}[{names[row]}][{names[col]}]"] = value[row * n + col]
                continue
            if len(value) == n:
                out.update({f"{key}[{name}]": v for name, v in zip(names, value, strict=True)})
                continue
        out[key] = value
    return out


def _write_topic(topic: str, messages: list[tuple[int, dict[str, Any]]], out_dir: Path,
                 export: CsvExport) -> None:
    labels = _constant_names(messages)
    messages = [(t, _named(message, labels)) for t, message in messages]
    lengths: dict[str, set[int]] = {}
    for _, message in messages:
        _array_lengths(message, "", lengths)
    variable = {name for name, seen in lengths.items() if len(seen) > 1}
    rows = []
    columns: dict[str, None] = {"log_time_ns": None}
    for log_time_ns, message in messages:
        row: dict[str, Any] = {"log_time_ns": log_time_ns}
        _flatten(message, "", variable, row)
        columns.update(dict.fromkeys(row))
        rows.append(row)
    path = out_dir / csv_name(topic)
    with open(path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_cell(row.get(column)) for column in columns])
    export.files[topic] = path
    export.rows[topic] = len(rows)
    # Only the outermost variable arrays matter: their contents were not visited.
    outer = sorted(name for name in variable
                   if not any(name.startswith(other + "[") for other in variable))
    if outer:
        export.skipped[topic] = outer


def export_csv(path: Path | str, out_dir: Path | str, topics: Iterable[str],
               head: int | None = None) -> CsvExport:
    """Write one CSV per topic into ``out_dir`` (created if missing); at most ``head`` rows
    per topic when given. Reads the file once; a truncated file gives what it holds."""
    out_dir = Path(out_dir)
    wanted = list(topics)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise CosimError(f"--csv {str(out_dir)!r}: cannot create the directory "
                         f"({error.strerror})") from None
    messages: dict[str, list[tuple[int, dict[str, Any]]]] = {topic: [] for topic in wanted}
    for topic, log_time_ns, message in iter_topics(path, set(wanted)):
        if head is None or len(messages[topic]) < head:
            messages[topic].append((log_time_ns, message))
    export = CsvExport()
    for topic in wanted:
        _write_topic(topic, messages[topic], out_dir, export)
    return export


def csv_command(summary: LogSummary, out_dir: str, topic: str | None,
                head: int | None) -> int:
    """`cosim inspect FILE --csv DIR [--topic T] [--head N]`: write the CSVs, print their
    paths (one per line, stdout) and what was left out or cut short (stderr)."""
    import sys

    topics = sorted(c.topic for c in summary.channels)
    if topic is not None and topic not in topics:
        raise CosimError(f"--topic {topic!r}: expected one of {', '.join(topics)}")
    if head is not None and head < 0:
        raise CosimError(f"--head {head}: expected a count >= 0")
    export = export_csv(summary.path, out_dir, [topic] if topic is not None else topics, head)
    for written in export.files.values():
        print(written)
    for name, arrays in export.skipped.items():
        print(f"cosim: {name}: skipped variable-length arrays: {', '.join(arrays)}",
              file=sys.stderr)
    if summary.truncated:
        print(f"cosim: {summary.path} is truncated: exported up to the last complete record",
              file=sys.stderr)
    return 0
