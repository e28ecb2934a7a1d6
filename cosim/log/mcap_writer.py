"""A minimal MCAP writer: what :class:`cosim.log.recorder.McapRecorder` needs, and fast.

MCAP is Foxglove's container for timestamped pub/sub messages; the format is the MCAP
specification (https://mcap.dev/spec, "MCAP Format Specification", major version 0). This
module writes the subset a run log uses: schemas, channels and messages in zstd-compressed
chunks, each chunk followed by its message indexes; metadata and attachments between the
chunks; and a complete summary section. The ``mcap`` package's own writer does the same
through a record object and a ``struct.pack`` call per field of each message; here a
message is one precompiled :class:`struct.Struct` ``pack``, two appends to the chunk's
bytearray and two to its channel's message index (``bench/log_writer.py`` measures both
writers on a run's messages).

The file, as written here::

    Magic Header
    Chunk [Schema Channel ... Message ...]  Message Index (one per channel in the chunk) ...
    Metadata | Attachment   (wherever the caller adds them, between chunks)
    ...
    Data End
    Schema ... Channel ... Statistics Chunk Index ... Attachment Index ... Metadata Index ...
    Summary Offset (one per group above)
    Footer Magic

Every record is ``opcode (uint8) | content length (uint64) | content``; integers are
little-endian; a String is a uint32 byte length and UTF-8 bytes, Bytes with a uint32 or
uint64 prefix likewise, a Map a uint32 byte length and its key-value pairs, an Array a
uint32 byte length and its elements. The record contents written here:

==================  ====  ================================================================
record              op    content
==================  ====  ================================================================
Header              0x01  profile (String), library (String)
Footer              0x02  summary_start (u64), summary_offset_start (u64), summary_crc (u32)
Schema              0x03  id (u16), name (String), encoding (String), data (u32 Bytes)
Channel             0x04  id (u16), schema_id (u16), topic (String), message_encoding
                          (String), metadata (Map<String, String>)
Message             0x05  channel_id (u16), sequence (u32), log_time (u64), publish_time
                          (u64), data (the rest of the record)
Chunk               0x06  message_start_time, message_end_time, uncompressed_size (u64 x 3),
                          uncompressed_crc (u32), compression (String), records (u64 Bytes)
Message Index       0x07  channel_id (u16), Array<(log_time u64, offset u64)>: each
                          message's offset from the start of the uncompressed records
Chunk Index         0x08  message_start_time, message_end_time, chunk_start_offset,
                          chunk_length (u64 x 4), message_index_offsets (Map<u16, u64>),
                          message_index_length (u64), compression (String),
                          compressed_size, uncompressed_size (u64 x 2)
Attachment          0x09  log_time, create_time (u64 x 2), name, media_type (String x 2),
                          data (u64 Bytes), crc (u32, CRC-32 of the fields before it)
Attachment Index    0x0A  offset, length, log_time, create_time, data_size (u64 x 5), name,
                          media_type (String x 2)
Statistics          0x0B  message_count (u64), schema_count (u16), channel_count,
                          attachment_count, metadata_count, chunk_count (u32 x 4),
                          message_start_time, message_end_time (u64 x 2),
                          channel_message_counts (Map<u16, u64>)
Metadata            0x0C  name (String), metadata (Map<String, String>)
Metadata Index      0x0D  offset, length (u64 x 2), name (String)
Summary Offset      0x0E  group_opcode (u8), group_start, group_length (u64 x 2)
Data End            0x0F  data_section_crc (u32)
==================  ====  ================================================================

Offsets are from the start of the file, lengths of a record include its 9-byte opcode and
length prefix. The CRCs are CRC-32 (:func:`zlib.crc32`): a chunk's of its uncompressed
records, an attachment's of its content before the crc field, Data End's of every byte
before it (magic and header included), the footer's of the summary and summary offset
sections and the footer's own opcode, length and two offsets. 0 would mean "not computed";
all four are computed here (the data section's costs a pass over the compressed bytes).

Crash safety: the writer makes one ``write`` call per finished chunk (the chunk and its
message indexes together), one per metadata or attachment record and one for the header
and for the end of the file; a stream that flushes every write (the recorder's) so holds
every finished chunk in the operating system, and a process killed mid-run leaves a file
that a streaming reader reads up to the last complete chunk.

Schemas and channels go into the chunk being filled, before the messages that use them, as
the specification's own examples place them, and again into the summary section, which
indexed readers need.
"""

from __future__ import annotations

import struct
import sys
import zlib
from array import array
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

import zstandard

MAGIC = b"\x89MCAP0\r\n"
"""The 8 bytes an MCAP file starts and ends with (``0x30``, ASCII 0: major version 0)."""

OP_HEADER = 0x01
OP_FOOTER = 0x02
OP_SCHEMA = 0x03
OP_CHANNEL = 0x04
OP_MESSAGE = 0x05
OP_CHUNK = 0x06
OP_MESSAGE_INDEX = 0x07
OP_CHUNK_INDEX = 0x08
OP_ATTACHMENT = 0x09
OP_ATTACHMENT_INDEX = 0x0A
OP_STATISTICS = 0x0B
OP_METADATA = 0x0C
OP_METADATA_INDEX = 0x0D
OP_SUMMARY_OFFSET = 0x0E
OP_DATA_END = 0x0F

DEFAULT_ZSTD_LEVEL = 1
"""zstd level of the chunks, chosen by ``bench/log_writer.py`` on a default run's chunks:
level 1 compresses markedly faster than zstd's default (3), and on these JSON chunks its
file is no larger (a little smaller, even); level 2 sits between them; the negative "fast"
levels save a little more time and leave a far larger file. The bench prints each level's
compression time and file size."""

_PREFIX = struct.Struct("<BQ")
"""Every record's opcode and content length."""

_MESSAGE_PREFIX = struct.Struct("<BQHIQQ")
"""A Message record up to its data: opcode, length, channel_id, sequence, log_time,
publish_time (31 bytes; the content length is 22 + the data's)."""
_MESSAGE_FIXED = 2 + 4 + 8 + 8

_CHUNK_PREFIX = struct.Struct("<BQQQQI")
"""A Chunk record up to its compression string: opcode, length, message_start_time,
message_end_time, uncompressed_size, uncompressed_crc."""

_MESSAGE_INDEX_PREFIX = struct.Struct("<BQHI")
"""A Message Index record up to its entries: opcode, length, channel_id, entries' bytes."""

_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_U16_U64 = struct.Struct("<HQ")
_SUMMARY_OFFSET = struct.Struct("<BQBQQ")
"""A whole Summary Offset record: opcode, length (17), group_opcode, group_start,
group_length."""
_FOOTER_FIELDS = struct.Struct("<BQQQ")
"""The Footer up to its CRC (what the CRC covers of it): opcode, length (20),
summary_start, summary_offset_start."""

_LITTLE_ENDIAN = sys.byteorder == "little"


class BinaryOutput(Protocol):
    """Where the file goes: anything with ``write(bytes)`` (a file opened ``"wb"``, the
    recorder's flushing stream, :class:`io.BytesIO`). The writer counts the bytes itself,
    so the stream must start empty and need not seek or tell."""

    def write(self, data: bytes, /) -> object: ...


def _string(value: str) -> bytes:
    """A String: uint32 byte length and UTF-8 bytes."""
    encoded = value.encode()
    return _U32.pack(len(encoded)) + encoded


def _string_map(values: Mapping[str, str]) -> bytes:
    """A Map<String, String>: uint32 byte length, then each key and value as a String."""
    body = b"".join(_string(key) + _string(value) for key, value in values.items())
    return _U32.pack(len(body)) + body


def _u16_u64_map(values: Mapping[int, int]) -> bytes:
    """A Map<uint16, uint64>: uint32 byte length, then each key and value."""
    body = b"".join(_U16_U64.pack(key, value) for key, value in values.items())
    return _U32.pack(len(body)) + body


def _record(opcode: int, content: bytes) -> bytes:
    """A whole record: opcode, content length and content."""
    return _PREFIX.pack(opcode, len(content)) + content


def _u64_bytes(values: array[int]) -> bytes:
    """An ``array('Q')`` as little-endian uint64s, whatever the machine's byte order."""
    if _LITTLE_ENDIAN:
        return values.tobytes()
    swapped = array("Q", values)
    swapped.byteswap()
    return swapped.tobytes()


@dataclass(frozen=True)
class _Chunked:
    """What the summary keeps of a written chunk: its Chunk Index record and figures."""

    index_record: bytes
    message_start_time: int
    message_end_time: int
    message_count: int


class McapWriter:
    """Writes one MCAP file to ``stream``: the header at once, then whatever is added, and
    the summary and footer at :meth:`finish`.

    ``chunk_size`` is the uncompressed size at which a chunk is finished and written (the
    first record that takes it past that size is the chunk's last); ``compression_level``
    the zstd level of the chunks.

    Schema and channel ids are given out from 1 in the order of :meth:`add_schema` and
    :meth:`add_channel`. :meth:`add_message` is the hot path and checks nothing: its
    channel id must be one :meth:`add_channel` gave, its times and sequence must fit
    uint64 and uint32, as the MCAP record has them.
    """

    def __init__(self, stream: BinaryOutput, *, chunk_size: int = 1024 * 1024,
                 compression_level: int = DEFAULT_ZSTD_LEVEL, profile: str = "",
                 library: str = "") -> None:
        self._stream = stream
        self._chunk_size = chunk_size
        self._compressor = zstandard.ZstdCompressor(level=compression_level)
        self._offset = 0
        """Bytes written so far: the file offset of the next record."""
        self._data_crc = 0
        """CRC-32 of every byte written so far (until Data End)."""
        self._chunk = bytearray()
        """The records of the chunk being filled, uncompressed."""
        self._chunk_index: dict[int, array[int]] = {}
        """The chunk being filled's message indexes: channel id to log time, offset, log
        time, offset, ... (uint64s), channels in the order of their first message."""
        self._schemas: list[bytes] = []
        self._channels: list[bytes] = []
        """Every Schema and Channel record, for the summary section."""
        self._chunks: list[_Chunked] = []
        self._channel_counts: dict[int, int] = {}
        self._attachment_indexes: list[bytes] = []
        self._metadata_indexes: list[bytes] = []
        self._finished = False
        self._write_data(MAGIC + _record(OP_HEADER, _string(profile) + _string(library)))

    def _write_data(self, data: bytes) -> None:
        """Bytes of the data section, in one ``write``."""
        self._stream.write(data)
        self._offset += len(data)
        self._data_crc = zlib.crc32(data, self._data_crc)

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        """A Schema record (into the chunk being filled); its id."""
        schema_id = len(self._schemas) + 1
        record = _record(OP_SCHEMA, _U16.pack(schema_id) + _string(name) + _string(encoding)
                         + _U32.pack(len(data)) + data)
        self._schemas.append(record)
        self._add_to_chunk(record)
        return schema_id

    def add_channel(self, topic: str, message_encoding: str, schema_id: int,
                    metadata: Mapping[str, str] | None = None) -> int:
        """A Channel record (into the chunk being filled); its id. ``schema_id`` 0 is a
        channel without a schema."""
        channel_id = len(self._channels) + 1
        record = _record(OP_CHANNEL, _U16.pack(channel_id) + _U16.pack(schema_id)
                         + _string(topic) + _string(message_encoding)
                         + _string_map(metadata or {}))
        self._channels.append(record)
        self._add_to_chunk(record)
        return channel_id

    def _add_to_chunk(self, record: bytes) -> None:
        self._chunk += record
        if len(self._chunk) > self._chunk_size:
            self._finish_chunk()

    def add_message(self, channel_id: int, log_time: int, publish_time: int, sequence: int,
                    data: bytes) -> None:
        """A Message record into the chunk being filled, and its entry in the chunk's
        message index; the chunk is written once it passes ``chunk_size``."""
        chunk = self._chunk
        index = self._chunk_index.get(channel_id)
        if index is None:
            index = self._chunk_index[channel_id] = array("Q")
        index.append(log_time)
        index.append(len(chunk))
        chunk += _MESSAGE_PREFIX.pack(OP_MESSAGE, _MESSAGE_FIXED + len(data), channel_id,
                                      sequence, log_time, publish_time)
        chunk += data
        if len(chunk) > self._chunk_size:
            self._finish_chunk()

    def flush(self) -> None:
        """Finish the chunk being filled now: a reader of the file so far (a run that dies
        next) sees every record added before."""
        self._finish_chunk()

    def _finish_chunk(self) -> None:
        """Compress and write the chunk being filled, its message indexes after it (one
        ``write``), and keep its Chunk Index for the summary. Nothing for an empty chunk."""
        records = self._chunk
        if not records:
            return
        message_count = 0
        start_time = end_time = 0
        for index in self._chunk_index.values():
            times = index[0::2]
            if message_count == 0:
                start_time, end_time = min(times), max(times)
            else:
                start_time, end_time = min(start_time, min(times)), max(end_time, max(times))
            message_count += len(times)
        compressed = self._compressor.compress(records)
        compression = _string("zstd")
        chunk_content_length = 8 * 3 + 4 + len(compression) + 8 + len(compressed)
        head = _CHUNK_PREFIX.pack(OP_CHUNK, chunk_content_length, start_time, end_time,
                                  len(records), zlib.crc32(records))
        chunk_start = self._offset
        chunk_length = 9 + chunk_content_length
        parts = [head, compression, _U64.pack(len(compressed)), compressed]
        index_offsets: dict[int, int] = {}
        index_offset = chunk_start + chunk_length
        counts = self._channel_counts
        for channel_id, index in self._chunk_index.items():
            entries = _u64_bytes(index)
            record_length = 9 + 2 + 4 + len(entries)
            parts.append(_MESSAGE_INDEX_PREFIX.pack(OP_MESSAGE_INDEX, record_length - 9,
                                                    channel_id, len(entries)))
            parts.append(entries)
            index_offsets[channel_id] = index_offset
            index_offset += record_length
            counts[channel_id] = counts.get(channel_id, 0) + len(index) // 2
        self._write_data(b"".join(parts))
        chunk_index = (_U64.pack(start_time) + _U64.pack(end_time) + _U64.pack(chunk_start)
                       + _U64.pack(chunk_length) + _u16_u64_map(index_offsets)
                       + _U64.pack(index_offset - chunk_start - chunk_length) + compression
                       + _U64.pack(len(compressed)) + _U64.pack(len(records)))
        self._chunks.append(_Chunked(_record(OP_CHUNK_INDEX, chunk_index), start_time,
                                     end_time, message_count))
        self._chunk = bytearray()
        self._chunk_index = {}

    def add_metadata(self, name: str, values: Mapping[str, str]) -> None:
        """A Metadata record, written at once (outside any chunk, as the spec requires)."""
        record = _record(OP_METADATA, _string(name) + _string_map(values))
        self._metadata_indexes.append(_record(
            OP_METADATA_INDEX, _U64.pack(self._offset) + _U64.pack(len(record)) + _string(name)))
        self._write_data(record)

    def add_attachment(self, name: str, media_type: str, data: bytes, log_time: int,
                       create_time: int = 0) -> None:
        """An Attachment record, written at once (outside any chunk); ``create_time`` 0 is
        "not known"."""
        fields = (_U64.pack(log_time) + _U64.pack(create_time) + _string(name)
                  + _string(media_type) + _U64.pack(len(data)) + data)
        record = _record(OP_ATTACHMENT, fields + _U32.pack(zlib.crc32(fields)))
        self._attachment_indexes.append(_record(
            OP_ATTACHMENT_INDEX, _U64.pack(self._offset) + _U64.pack(len(record))
            + _U64.pack(log_time) + _U64.pack(create_time) + _U64.pack(len(data))
            + _string(name) + _string(media_type)))
        self._write_data(record)

    def finish(self) -> None:
        """Write the last chunk, Data End, the summary section (schemas, channels,
        statistics, chunk, attachment and metadata indexes), the summary offsets, the
        footer and the closing magic, in one ``write``. Idempotent; the stream stays open."""
        if self._finished:
            return
        self._finished = True
        self._finish_chunk()
        self._write_data(_record(OP_DATA_END, _U32.pack(self._data_crc)))
        summary_start = self._offset
        with_messages = [chunk for chunk in self._chunks if chunk.message_count]
        message_count = sum(chunk.message_count for chunk in with_messages)
        statistics = (
            _U64.pack(message_count) + _U16.pack(len(self._schemas))
            + _U32.pack(len(self._channels)) + _U32.pack(len(self._attachment_indexes))
            + _U32.pack(len(self._metadata_indexes)) + _U32.pack(len(self._chunks))
            + _U64.pack(min((c.message_start_time for c in with_messages), default=0))
            + _U64.pack(max((c.message_end_time for c in with_messages), default=0))
            + _u16_u64_map(dict(sorted(self._channel_counts.items()))))
        groups = (
            (OP_SCHEMA, self._schemas),
            (OP_CHANNEL, self._channels),
            (OP_STATISTICS, [_record(OP_STATISTICS, statistics)]),
            (OP_CHUNK_INDEX, [chunk.index_record for chunk in self._chunks]),
            (OP_ATTACHMENT_INDEX, self._attachment_indexes),
            (OP_METADATA_INDEX, self._metadata_indexes),
        )
        summary: list[bytes] = []
        offsets: list[bytes] = []
        position = summary_start
        for opcode, records in groups:
            if not records:
                continue
            group = b"".join(records)
            summary.append(group)
            offsets.append(_SUMMARY_OFFSET.pack(OP_SUMMARY_OFFSET, 17, opcode, position,
                                                len(group)))
            position += len(group)
        summary_offset_start = position
        footer = _FOOTER_FIELDS.pack(OP_FOOTER, 20, summary_start, summary_offset_start)
        tail = b"".join(summary) + b"".join(offsets) + footer
        self._stream.write(tail + _U32.pack(zlib.crc32(tail)) + MAGIC)
        self._offset += len(tail) + 4 + len(MAGIC)
