"""Reading cosim's MCAP logs back: channels, counts, metadata, metrics and messages.

The file is scanned record by record with the ``mcap`` package's stream reader, so a log
whose writer was killed (no summary section, a cut-off last chunk) is read up to its last
complete record and reported as truncated.

Log times are ``epoch + sim time`` (``sim.epoch``, so that Foxglove shows real dates); the
``run`` metadata, written before any message, holds ``epoch_ns``, and every reader here
subtracts it: the ``log_time_ns`` they yield is sim time, as in logs without an epoch.
"""

from __future__ import annotations

import json
import struct
import zlib
from collections.abc import Container, Iterator, Sequence
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import Any

import orjson
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Chunk, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, get_chunk_data_stream
from zstandard import ZstdError

from cosim.core.exceptions import LogReadError
from cosim.log import topics


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
    """The writer named in the MCAP header (foxglove-sdk's for cosim's logs; ``cosim
    <version>`` for those of cosim's own writer, before 2026-12)."""

    @property
    def written_by_cosim(self) -> bool:
        """A cosim run's log: its ``run`` metadata names cosim's version (logs of cosim's
        own writer named it in the header too)."""
        return "version_cosim" in self.metadata.get("run", {}) or \
            self.library.startswith("cosim")

    @property
    def duration_s(self) -> float:
        if self.start_ns is None or self.end_ns is None:
            return 0.0
        return (self.end_ns - self.start_ns) / 1e9

    @property
    def epoch_ns(self) -> int:
        """Log time of sim time 0 [ns since the Unix epoch]; 0 for logs without one."""
        return _epoch_ns(self.metadata.get("run", {}))

    @property
    def message_count(self) -> int:
        return sum(c.message_count for c in self.channels)

    @property
    def config(self) -> dict[str, Any]:
        return _json_object(self.metadata.get("run", {}).get("config_json"))

    @property
    def versions(self) -> dict[str, str]:
        return _json_object(self.metadata.get("run", {}).get("versions"))


def log_file_problem(path: Path) -> str | None:
    """Why ``path`` cannot be a log to read, in a few words for a one-line error (``no such
    file``, ``is a folder``, ``not a regular file``); None for a file worth trying."""
    if path.is_file():
        return None
    if path.is_dir():
        return "is a folder"
    return "not a regular file" if path.exists() else "no such file"


def _json_object(text: str | None) -> dict[str, Any]:
    """A JSON object from metadata; {} when absent or not one (another writer's)."""
    try:
        value = json.loads(text) if text else {}
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def _epoch_ns(run_metadata: dict[str, str]) -> int:
    try:
        return int(run_metadata.get("epoch_ns", "0"))
    except ValueError:
        return 0


DAMAGE_ERRORS: tuple[type[BaseException], ...] = (
    McapError, EOFError, ValueError, OSError, struct.error, ZstdError,
    RuntimeError,  # lz4's
    MemoryError)
"""What reading a log's records raises at a truncation or at damaged bytes: a scan stops
there quietly (:func:`_records`, :func:`_read_chunks`)."""
SUMMARY_ERRORS: tuple[type[BaseException], ...] = (
    McapError, EOFError, ValueError, OSError, struct.error, KeyError, ZstdError)
"""What reading a summary section that is missing or damaged raises: the caller then scans
the file record by record."""


def _records(path: Path, messages_of: Container[int] | None = None) -> Iterator[Any]:
    """Every record of the file, the chunks' records in their place; stops quietly at a
    truncation or at corrupted bytes (a chunk that does not decompress, a bad CRC, a record
    that does not parse), which it reports by yielding ``None`` last.

    ``messages_of``: the channel ids whose Message records are wanted (a container the
    caller may fill as the Channel records arrive); the others are stepped over without
    being decoded (:func:`_chunk_records`). None: every message."""
    try:
        stream = open(path, "rb")  # noqa: SIM115 - closed in finally
    except OSError as error:
        raise LogReadError(f"{str(path)!r}: cannot open ({error.strerror})") from None
    try:
        reader = StreamReader(stream, skip_magic=False, emit_chunks=True)
        saw_footer = False
        try:
            for record in reader.records:
                if isinstance(record, Chunk):
                    yield from _chunk_records(record, messages_of)
                    continue
                if isinstance(record, Footer):
                    saw_footer = True
                yield record
        except DAMAGE_ERRORS as error:
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


MESSAGE_OPCODE = 0x05
"""MCAP's opcode of a Message record (the MCAP specification, "Records")."""
MESSAGE_HEADER = struct.Struct("<HIQQ")
"""A Message record's fields before its data: channel id (uint16), sequence (uint32), log
time and publish time (uint64 each), little-endian (the MCAP specification, "Message")."""
RECORD_HEADER = struct.Struct("<BQ")
"""Every record's opcode (uint8) and the length of its content (uint64)."""


def _chunk_records(chunk: Chunk, messages_of: Container[int] | None) -> Iterator[Any]:
    """The records of one chunk, in order: its Schema and Channel records decoded by the
    ``mcap`` package, its Message records built here from their fixed header, and only
    those of ``messages_of``'s channels (every one when it is None). ``mcap``'s own
    ``breakup_chunk`` decodes every record through a byte stream, a Python call a field:
    most of the time of reading a log back for a few of its 20 topics. A chunk whose bytes
    do not match its CRC is a ``ValueError`` (``mcap``'s CRCValidationError), a record that
    runs past the chunk's end a :class:`McapError`."""
    stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    data = stream.read(size)
    offset = 0
    while offset < size:
        opcode, length = RECORD_HEADER.unpack_from(data, offset)
        start = offset + RECORD_HEADER.size
        offset = start + length
        if offset > size:
            raise McapError(f"a record of {length} bytes runs past its chunk's end")
        if opcode == MESSAGE_OPCODE:
            channel_id, sequence, log_time, publish_time = MESSAGE_HEADER.unpack_from(
                data, start)
            if messages_of is None or channel_id in messages_of:
                yield Message(channel_id=channel_id, sequence=sequence, log_time=log_time,
                              publish_time=publish_time,
                              data=data[start + MESSAGE_HEADER.size:offset])
        elif opcode == Opcode.CHANNEL:
            yield Channel.read(ReadDataStream(BytesIO(data[start:offset])))
        elif opcode == Opcode.SCHEMA:
            yield Schema.read(ReadDataStream(BytesIO(data[start:offset])))


CHUNK_OPCODE = 0x06
"""MCAP's opcode of a Chunk record (the MCAP specification, "Records")."""


def _chunks_intact(stream: Any, chunk_indexes: Sequence[Any]) -> bool:
    """Whether every chunk the summary indexes is where the index says and decompresses to
    its CRC: the summary section alone cannot show damaged bytes in the data section. A
    chunk record is opcode (1 byte), length (uint64), then start and end time (2 x uint64),
    uncompressed size (uint64), uncompressed CRC-32 (uint32, 0 = none), the compression
    (uint32-prefixed string) and the records (uint64-prefixed bytes), all little-endian.
    Reading and decompressing the bytes costs milliseconds; no record is decoded."""
    for index in chunk_indexes:
        stream.seek(index.chunk_start_offset)
        record = stream.read(index.chunk_length)
        if len(record) != index.chunk_length or record[0] != CHUNK_OPCODE:
            return False
        if int.from_bytes(record[1:9], "little") != index.chunk_length - 9:
            return False
        size = int.from_bytes(record[25:33], "little")
        crc = int.from_bytes(record[33:37], "little")
        name_length = int.from_bytes(record[37:41], "little")
        compression = record[41:41 + name_length].decode("ascii", "replace")
        start = 41 + name_length + 8
        data = record[start:start + int.from_bytes(record[start - 8:start], "little")]
        try:
            if compression == "zstd":
                data = zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
            elif compression:
                continue  # lz4 and others: left to the mcap reader
        except ZstdError:
            return False
        if len(data) != size or (crc and zlib.crc32(data) != crc):
            return False
    return True


def _indexed_summary(path: Path) -> LogSummary | None:
    """The summary from the file's summary section (statistics, channels, schemas, metadata
    and attachment indexes) and the one chunk that holds ``/metrics``: milliseconds for a
    complete file. None when the file has no complete summary section (a run cut off, or
    another writer), and the caller scans the records instead."""
    try:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            found = reader.get_summary()
            if found is None or found.statistics is None:
                return None
            if not _chunks_intact(stream, found.chunk_indexes):
                return None  # the record-by-record scan says where the damage is
            statistics = found.statistics
            summary = LogSummary(path)
            summary.library = reader.get_header().library
            if statistics.message_count:
                summary.start_ns = statistics.message_start_time
                summary.end_ns = statistics.message_end_time
            for channel_id, channel in found.channels.items():
                schema = found.schemas.get(channel.schema_id)
                summary.channels.append(ChannelSummary(
                    topic=channel.topic,
                    schema_name=schema.name if schema else "",
                    schema_encoding=schema.encoding if schema else "",
                    message_encoding=channel.message_encoding,
                    message_count=statistics.channel_message_counts.get(channel_id, 0),
                ))
            summary.metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            summary.attachments = [a.name for a in found.attachment_indexes]
            for _, _, message in reader.iter_messages(topics=[topics.METRICS]):
                summary.metrics = _metrics(message.data)
            return summary
    except SUMMARY_ERRORS:
        return None


def read_summary(path: Path | str) -> LogSummary:
    """Scan a log: channels with schema and count, time range, metadata, metrics.

    A complete file is read through its summary section and indexes; a truncated one
    record by record up to its last complete record (``truncated``)."""
    path = Path(path)
    indexed = _indexed_summary(path) if path.is_file() else None
    return indexed if indexed is not None else _scan_summary(path)


def _scan_summary(path: Path) -> LogSummary:
    """:func:`read_summary` record by record (what a file without a summary section takes)."""
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
            if channel is not None and channel.topic == topics.METRICS:
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
        message = orjson.loads(data)  # 5x json's speed on the estimate's covariances
    except ValueError:  # orjson.JSONDecodeError is one
        raise LogReadError(f"topic {topic!r}: a message is not JSON: expected a log that "
                           "cosim wrote (JSON messages)") from None
    return message if isinstance(message, dict) else {"value": message}


def iter_messages(path: Path | str, topic: str) -> Iterator[tuple[int, dict[str, Any]]]:
    """``(log_time_ns, message)`` of one topic, in file order (JSON-decoded); the time is
    sim time (the log's epoch subtracted); a truncated file ends at its last complete
    record (:func:`iter_topics`)."""
    for _, log_time_ns, message in iter_topics(path, {topic}):
        yield log_time_ns, message


def iter_topics(path: Path | str, topics: set[str] | None = None
                ) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """``(topic, log_time_ns, message)`` of several topics (all when ``topics`` is None) in
    one pass, in file order (JSON-decoded); a truncated file ends at its last complete
    record.

    A complete file is read through its summary section: its channels, its ``run``
    metadata and the chunks that hold the topics, found by their indexes
    (:func:`_indexed_messages`); a file without one record by record."""
    path = Path(path)
    indexed = _indexed_messages(path, topics) if path.is_file() else None
    if indexed is not None:
        for topic, log_time_ns, data in indexed:
            yield topic, log_time_ns, _decoded(topic, data)
        return
    names: dict[int, str] = {}
    epoch = 0
    for record in _records(path, messages_of=names):
        if isinstance(record, Channel) and (topics is None or record.topic in topics):
            names[record.id] = record.topic
        elif isinstance(record, Metadata) and record.name == "run":
            epoch = _epoch_ns(dict(record.metadata))
        elif isinstance(record, Message) and record.channel_id in names:
            topic = names[record.channel_id]
            yield topic, record.log_time - epoch, _decoded(topic, record.data)


def _indexed_messages(path: Path, topics: set[str] | None
                      ) -> Iterator[tuple[str, int, bytes]] | None:
    """``(topic, log_time_ns, data)`` of ``topics`` (every topic when None) in file order,
    read through the file's summary section: the channels and the ``run`` metadata from
    it, and only the chunks its chunk indexes say hold one of the topics, each split by
    :func:`_chunk_records`, so that neither the message index records (one pair of numbers
    per message) nor the other channels' messages are decoded. None when the file has no
    summary section (a run cut off, or another writer): the caller scans it instead.
    Damaged bytes in a chunk end the messages there, as a scan ends them."""
    try:
        stream = open(path, "rb")  # noqa: SIM115 - closed by _read_chunks, or here
    except OSError:
        return None
    try:
        reader = make_reader(stream)
        summary = reader.get_summary()
        epoch = 0 if summary is None else next(
            (_epoch_ns(dict(m.metadata)) for m in reader.iter_metadata() if m.name == "run"), 0)
    except SUMMARY_ERRORS:
        summary = None
    if summary is None:
        stream.close()
        return None
    names = {channel_id: channel.topic for channel_id, channel in summary.channels.items()
             if topics is None or channel.topic in topics}
    chunks = sorted((index for index in summary.chunk_indexes
                     if any(channel in names for channel in index.message_index_offsets)),
                    key=lambda index: index.chunk_start_offset)
    return _read_chunks(stream, chunks, names, epoch)


def _read_chunks(stream: Any, chunk_indexes: Sequence[Any], names: dict[int, str],
                 epoch_ns: int) -> Iterator[tuple[str, int, bytes]]:
    """The messages of ``names``' channels in the chunks ``chunk_indexes`` locate; closes
    ``stream`` at the end."""
    with stream:
        for index in chunk_indexes:
            try:
                stream.seek(index.chunk_start_offset + RECORD_HEADER.size)
                records = list(_chunk_records(Chunk.read(ReadDataStream(stream)), names))
            except DAMAGE_ERRORS:
                return
            for record in records:
                if isinstance(record, Message):
                    yield names[record.channel_id], record.log_time - epoch_ns, record.data


def read_attachment(path: Path | str, name: str) -> bytes | None:
    """The data of the first attachment called ``name`` (e.g. ``sedan.xml``, the MJCF
    actually simulated), or None if the log has none (or was cut off before it)."""
    for record in _records(Path(path), messages_of=()):
        if isinstance(record, Attachment) and record.name == name:
            return bytes(record.data)
    return None
