"""Reading cosim's MCAP logs back: channels, counts, metadata, metrics and messages.

The file is scanned record by record with the ``mcap`` package's stream reader, so a log
whose writer was killed (no summary section, a cut-off last chunk) is read up to its last
complete record and reported as truncated.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.records import Attachment, Channel, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from zstandard import ZstdError

from cosim.exceptions import LogReadError


@dataclass(frozen=True)
class ChannelSummary:
    topic: str
    schema_name: str
    schema_encoding: str
    message_encoding: str
    message_count: int


@dataclass
class LogSummary:
    """What a log holds."""

    path: Path
    channels: list[ChannelSummary] = field(default_factory=list)
    start_ns: int | None = None
    end_ns: int | None = None
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: list[str] = field(default_factory=list)
    metrics: dict[str, Any] | None = None
    truncated: bool = False
    library: str = ""
    """The writer named in the MCAP header (``cosim <version>`` for cosim's logs)."""

    @property
    def written_by_cosim(self) -> bool:
        return self.library.startswith("cosim")

    @property
    def duration_s(self) -> float:
        if self.start_ns is None or self.end_ns is None:
            return 0.0
        return (self.end_ns - self.start_ns) / 1e9

    @property
    def message_count(self) -> int:
        return sum(c.message_count for c in self.channels)

    @property
    def config(self) -> dict[str, Any]:
        return _json_object(self.metadata.get("run", {}).get("config_json"))

    @property
    def versions(self) -> dict[str, str]:
        return _json_object(self.metadata.get("run", {}).get("versions"))


def _json_object(text: str | None) -> dict[str, Any]:
    """A JSON object from metadata; {} when absent or not one (another writer's)."""
    try:
        value = json.loads(text) if text else {}
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def _records(path: Path) -> Iterator[Any]:
    """Every record of the file; stops quietly at a truncation or at corrupted bytes (a
    chunk that does not decompress, a bad CRC, a record that does not parse), which it
    reports by yielding ``None`` last."""
    try:
        stream = open(path, "rb")  # noqa: SIM115 - closed in finally
    except OSError as error:
        raise LogReadError(f"{str(path)!r}: cannot open ({error.strerror})") from None
    try:
        reader = StreamReader(stream, skip_magic=False, emit_chunks=False)
        saw_footer = False
        try:
            for record in reader.records:
                if isinstance(record, Footer):
                    saw_footer = True
                yield record
        except (McapError, EOFError, ValueError, OSError, struct.error,
                ZstdError, RuntimeError, MemoryError) as error:  # lz4 raises RuntimeError
            if not saw_footer and stream.tell() <= 8:
                raise LogReadError(
                    f"{str(path)!r}: not an MCAP file ({error})"
                ) from None
            yield None
            return
        if not saw_footer:
            yield None
    finally:
        stream.close()


def read_summary(path: Path | str) -> LogSummary:
    """Scan a log: channels with schema and count, time range, metadata, metrics."""
    path = Path(path)
    summary = LogSummary(path)
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    counts: dict[int, int] = {}
    for record in _records(path):
        if record is None:
            summary.truncated = True
        elif isinstance(record, Header):
            summary.library = record.library
        elif isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            channels.setdefault(record.id, record)
            counts.setdefault(record.id, 0)
        elif isinstance(record, Message):
            counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
            if summary.start_ns is None or record.log_time < summary.start_ns:
                summary.start_ns = record.log_time
            if summary.end_ns is None or record.log_time > summary.end_ns:
                summary.end_ns = record.log_time
            channel = channels.get(record.channel_id)
            if channel is not None and channel.topic == "/metrics":
                summary.metrics = _metrics(record.data)
        elif isinstance(record, Metadata):
            summary.metadata[record.name] = dict(record.metadata)
        elif isinstance(record, Attachment):
            summary.attachments.append(record.name)
    for channel_id, channel in channels.items():
        schema = schemas.get(channel.schema_id)
        summary.channels.append(ChannelSummary(
            topic=channel.topic,
            schema_name=schema.name if schema else "",
            schema_encoding=schema.encoding if schema else "",
            message_encoding=channel.message_encoding,
            message_count=counts.get(channel_id, 0),
        ))
    if not summary.channels and summary.truncated:
        raise LogReadError(f"{str(path)!r}: no complete MCAP records")
    return summary


def _metrics(data: bytes) -> dict[str, Any] | None:
    try:
        metrics = json.loads(data)
    except ValueError:  # UnicodeDecodeError included: not cosim's JSON
        return None
    return metrics if isinstance(metrics, dict) else None


def _decoded(topic: str, data: bytes) -> dict[str, Any]:
    try:
        message = json.loads(data)
    except ValueError:
        raise LogReadError(f"topic {topic!r}: a message is not JSON: expected a log that "
                           "cosim wrote (JSON messages)") from None
    return message if isinstance(message, dict) else {"value": message}


def iter_messages(path: Path | str, topic: str) -> Iterator[tuple[int, dict[str, Any]]]:
    """``(log_time_ns, message)`` of one topic, in file order (JSON-decoded)."""
    wanted: set[int] = set()
    for record in _records(Path(path)):
        if isinstance(record, Channel) and record.topic == topic:
            wanted.add(record.id)
        elif isinstance(record, Message) and record.channel_id in wanted:
            yield record.log_time, _decoded(topic, record.data)


def iter_topics(path: Path | str, topics: set[str] | None = None
                ) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """``(topic, log_time_ns, message)`` of several topics (all when ``topics`` is None) in
    one pass, in file order (JSON-decoded); a truncated file ends at its last complete
    record."""
    names: dict[int, str] = {}
    for record in _records(Path(path)):
        if isinstance(record, Channel) and (topics is None or record.topic in topics):
            names[record.id] = record.topic
        elif isinstance(record, Message) and record.channel_id in names:
            topic = names[record.channel_id]
            yield topic, record.log_time, _decoded(topic, record.data)


def read_attachment(path: Path | str, name: str) -> bytes | None:
    """The data of the first attachment called ``name`` (e.g. ``sedan.xml``, the MJCF
    actually simulated), or None if the log has none (or was cut off before it)."""
    for record in _records(Path(path)):
        if isinstance(record, Attachment) and record.name == name:
            return bytes(record.data)
    return None
