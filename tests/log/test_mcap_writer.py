"""cosim's own MCAP writer (:mod:`cosim.log.mcap_writer`) read back by the ``mcap`` package.

Every file here is read with mcap's readers, the indexed one (seeking: summary, chunk
indexes, message indexes) and the streaming one (record by record, CRCs validated), and
its bytes are checked where a reader would trust them without looking (index offsets and
lengths, the footer's CRC). The recorder's files are compared with what mcap's own Writer
makes of the same calls.
"""

from __future__ import annotations

import io
import json
import struct
import zlib
from pathlib import Path
from typing import Any

import pytest
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Chunk, DataEnd, Footer, Header, Message, MessageIndex
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from cosim.log.mcap_writer import McapWriter
from cosim.log.reader import read_summary
from cosim.log.recorder import McapRecorder

TOPICS = ("/a", "/b", "/c")
EPOCH_NS = 1_767_225_600_000_000_000


def _payload(i: int) -> bytes:
    return json.dumps({"i": i, "x": [i * 0.1] * (i % 5)}).encode()


def _write(stream: Any, n_messages: int = 200, chunk_size: int = 2000) -> list[tuple]:
    """A file with three channels (two schemas), ``n_messages`` messages over several
    chunks, two metadata and an attachment; the messages as (channel id, log time,
    publish time, sequence, data)."""
    writer = McapWriter(stream, chunk_size=chunk_size, library="test")
    first = writer.add_schema("A", "jsonschema", b'{"type": "object"}')
    second = writer.add_schema("B", "jsonschema", b'{"title": "B"}')
    channels = [writer.add_channel("/a", "json", first),
                writer.add_channel("/b", "json", first, {"k": "v"}),
                writer.add_channel("/c", "json", second)]
    writer.add_metadata("run", {"seed": "0", "epoch_ns": str(EPOCH_NS)})
    messages = []
    for i in range(n_messages):
        channel = channels[i % 3] if i % 7 else channels[0]
        message = (channel, EPOCH_NS + i * 1_000_000, EPOCH_NS + i * 1_000_000 + 5, i, _payload(i))
        writer.add_message(*message)
        messages.append(message)
    writer.add_attachment("model.xml", "application/xml", b"<mujoco/>" * 50,
                          log_time=EPOCH_NS + 7, create_time=EPOCH_NS + 3)
    writer.add_metadata("metrics", {"cte_max_m": "0.05"})
    writer.finish()
    return messages


@pytest.fixture
def written() -> tuple[bytes, list[tuple]]:
    stream = io.BytesIO()
    messages = _write(stream)
    return stream.getvalue(), messages


def _records_at(data: bytes, offset: int, length: int) -> list[tuple[int, bytes]]:
    """The (opcode, content) of the records in ``data[offset:offset + length]``."""
    records = []
    end = offset + length
    while offset < end:
        opcode, content_length = struct.unpack_from("<BQ", data, offset)
        records.append((opcode, data[offset + 9:offset + 9 + content_length]))
        offset += 9 + content_length
    assert offset == end, "records overrun the stated length"
    return records


def test_indexed_reader_reads_back_every_message_and_the_statistics(
        written: tuple[bytes, list[tuple]]) -> None:
    data, messages = written
    reader = make_reader(io.BytesIO(data), validate_crcs=True)
    assert reader.get_header().library == "test"
    summary = reader.get_summary()
    assert summary is not None and summary.statistics is not None
    read = [(channel.id, m.log_time, m.publish_time, m.sequence, m.data)
            for _, channel, m in reader.iter_messages(log_time_order=False)]
    assert read == messages
    statistics = summary.statistics
    assert statistics.message_count == len(messages)
    assert statistics.schema_count == 2 and statistics.channel_count == 3
    assert statistics.attachment_count == 1 and statistics.metadata_count == 2
    assert statistics.chunk_count == len(summary.chunk_indexes) > 3
    assert statistics.message_start_time == messages[0][1]
    assert statistics.message_end_time == messages[-1][1]
    counts: dict[int, int] = {}
    for message in messages:
        counts[message[0]] = counts.get(message[0], 0) + 1
    assert dict(statistics.channel_message_counts) == counts
    assert {c.topic: (c.schema_id, c.metadata) for c in summary.channels.values()} == {
        "/a": (1, {}), "/b": (1, {"k": "v"}), "/c": (2, {})}
    assert {s.id: (s.name, s.data) for s in summary.schemas.values()} == {
        1: ("A", b'{"type": "object"}'), 2: ("B", b'{"title": "B"}')}
    # a time window is served through the chunk indexes' times
    window = [m.sequence for _, _, m in reader.iter_messages(
        starting_at=messages[50][1], ending_before=messages[60][1])]
    assert window == list(range(50, 60))


def test_streaming_reader_reads_every_record_and_validates_the_crcs(
        written: tuple[bytes, list[tuple]]) -> None:
    data, messages = written
    records = list(StreamReader(io.BytesIO(data), validate_crcs=True).records)
    assert isinstance(records[0], Header) and isinstance(records[-1], Footer)
    assert sum(isinstance(r, DataEnd) for r in records) == 1
    data_end = next(r for r in records if isinstance(r, DataEnd))
    (summary_start,) = struct.unpack_from("<Q", data, len(data) - 8 - 29 + 9)
    assert data_end.data_section_crc == zlib.crc32(data[:summary_start - 13]) != 0
    streamed = [(m.channel_id, m.log_time, m.publish_time, m.sequence, m.data)
                for m in records if isinstance(m, Message)]
    assert streamed == messages


def test_chunk_indexes_point_at_their_chunks(written: tuple[bytes, list[tuple]]) -> None:
    data, messages = written
    summary = make_reader(io.BytesIO(data)).get_summary()
    assert summary is not None
    in_chunks = 0
    previous_end = 0
    for index in summary.chunk_indexes:
        opcode, content = _records_at(data, index.chunk_start_offset, index.chunk_length)[0]
        assert opcode == 0x06
        start, end, size, crc = struct.unpack_from("<QQQI", content)
        (name_length,) = struct.unpack_from("<I", content, 28)
        assert content[32:32 + name_length] == b"zstd" and index.compression == "zstd"
        (compressed_size,) = struct.unpack_from("<Q", content, 32 + name_length)
        assert compressed_size == index.compressed_size
        records = zstandard.ZstdDecompressor().decompress(
            content[40 + name_length:], max_output_size=size)
        assert len(records) == size == index.uncompressed_size
        assert crc == zlib.crc32(records) != 0
        assert (start, end) == (index.message_start_time, index.message_end_time)
        chunk_messages = [r for r in _records_at(records, 0, len(records)) if r[0] == 0x05]
        times = [struct.unpack_from("<Q", r[1], 6)[0] for r in chunk_messages]
        assert (min(times), max(times)) == (start, end)
        assert start >= previous_end
        previous_end = end
        in_chunks += len(chunk_messages)
        # the chunk's message indexes follow it, exactly message_index_length bytes
        after = index.chunk_start_offset + index.chunk_length
        following = _records_at(data, after, index.message_index_length)
        assert [opcode for opcode, _ in following] == [0x07] * len(index.message_index_offsets)
    assert in_chunks == len(messages)


def test_message_indexes_give_each_message_of_the_chunk(
        written: tuple[bytes, list[tuple]]) -> None:
    data, messages = written
    stream = io.BytesIO(data)
    summary = make_reader(stream).get_summary()
    assert summary is not None
    indexed = []
    for chunk_index in summary.chunk_indexes:
        stream.seek(chunk_index.chunk_start_offset + 9)
        chunk = Chunk.read(_stream(stream))
        records = zstandard.ZstdDecompressor().decompress(
            chunk.data, max_output_size=chunk.uncompressed_size)
        for channel_id, offset in chunk_index.message_index_offsets.items():
            opcode, content = _records_at(data, offset, 9 + struct.unpack_from(
                "<Q", data, offset + 1)[0])[0]
            assert opcode == 0x07
            index = MessageIndex.read(_stream(io.BytesIO(content)))
            assert index.channel_id == channel_id and index.records
            for log_time, message_offset in index.records:
                opcode, content = _records_at(records, message_offset, 9 + struct.unpack_from(
                    "<Q", records, message_offset + 1)[0])[0]
                assert opcode == 0x05
                channel, sequence, log, publish = struct.unpack_from("<HIQQ", content)
                assert (channel, log) == (channel_id, log_time)
                indexed.append((channel, log, publish, sequence, content[22:]))
    assert sorted(indexed, key=lambda m: m[3]) == messages


def _stream(raw: io.BytesIO) -> ReadDataStream:
    return ReadDataStream(raw)


def test_metadata_and_attachment_are_indexed_and_read_back(
        written: tuple[bytes, list[tuple]]) -> None:
    data, _ = written
    reader = make_reader(io.BytesIO(data), validate_crcs=True)
    assert [(m.name, m.metadata) for m in reader.iter_metadata()] == [
        ("run", {"seed": "0", "epoch_ns": str(EPOCH_NS)}), ("metrics", {"cte_max_m": "0.05"})]
    attachments = list(reader.iter_attachments())
    assert [(a.name, a.media_type, a.log_time, a.create_time, a.data) for a in attachments] == [
        ("model.xml", "application/xml", EPOCH_NS + 7, EPOCH_NS + 3, b"<mujoco/>" * 50)]
    summary = reader.get_summary()
    assert summary is not None
    for index in summary.metadata_indexes:
        assert _records_at(data, index.offset, index.length)[0][0] == 0x0C
    (attachment_index,) = summary.attachment_indexes
    assert attachment_index.data_size == 9 * 50
    opcode, content = _records_at(data, attachment_index.offset, attachment_index.length)[0]
    assert opcode == 0x09
    assert struct.unpack("<I", content[-4:])[0] == zlib.crc32(content[:-4])


def test_summary_offsets_and_footer_crc(written: tuple[bytes, list[tuple]]) -> None:
    data, _ = written
    assert data[:8] == data[-8:] == b"\x89MCAP0\r\n"
    footer_start = len(data) - 8 - 29
    opcode, length, summary_start, offsets_start, crc = struct.unpack_from(
        "<BQQQI", data, footer_start)
    assert (opcode, length) == (0x02, 20)
    assert crc == zlib.crc32(data[summary_start:footer_start + 25])
    assert data[summary_start - 13] == 0x0F  # Data End just before the summary
    groups = {}
    for opcode, content in _records_at(data, offsets_start, footer_start - offsets_start):
        assert opcode == 0x0E
        group_opcode, group_start, group_length = struct.unpack("<BQQ", content)
        groups[group_opcode] = {o for o, _ in _records_at(data, group_start, group_length)}
    assert groups == {0x03: {0x03}, 0x04: {0x04}, 0x0B: {0x0B}, 0x08: {0x08},
                      0x0A: {0x0A}, 0x0D: {0x0D}}


def test_an_empty_file_is_valid() -> None:
    stream = io.BytesIO()
    McapWriter(stream, library="empty").finish()
    data = stream.getvalue()
    reader = make_reader(io.BytesIO(data), validate_crcs=True)
    summary = reader.get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == summary.statistics.chunk_count == 0
    assert summary.statistics.message_start_time == summary.statistics.message_end_time == 0
    assert summary.chunk_indexes == [] and list(reader.iter_messages()) == []
    kinds = [type(r).__name__ for r in StreamReader(io.BytesIO(data), validate_crcs=True).records]
    assert kinds == ["Header", "DataEnd", "Statistics", "SummaryOffset", "Footer"]


def test_channels_without_messages_are_kept_in_a_chunk() -> None:
    stream = io.BytesIO()
    writer = McapWriter(stream)
    writer.add_channel("/quiet", "json", writer.add_schema("Q", "jsonschema", b"{}"))
    writer.finish()
    records = list(StreamReader(io.BytesIO(stream.getvalue()), validate_crcs=True).records)
    assert [type(r).__name__ for r in records][:3] == ["Header", "Schema", "Channel"]
    summary = make_reader(io.BytesIO(stream.getvalue())).get_summary()
    assert summary is not None and summary.statistics is not None
    assert [c.topic for c in summary.channels.values()] == ["/quiet"]
    assert summary.statistics.chunk_count == 1 and summary.statistics.message_count == 0


def _record_run(recorder: McapRecorder, n_messages: int) -> None:
    for topic in TOPICS:
        recorder.register(topic, {"title": f"test{topic.replace('/', '.')}", "type": "object"})
    recorder.add_metadata("run", {"epoch_ns": str(EPOCH_NS)})
    for i in range(n_messages):
        recorder.write(TOPICS[i % 3], i * 0.002, {"i": i, "values": [i * 0.5] * 20})


def test_recorder_file_matches_mcap_writer_of_the_same_calls(tmp_path: Path) -> None:
    """The same topics, messages, metadata and attachment through mcap's own Writer (as
    the recorder wrote them before) decode to the same content."""
    path = tmp_path / "ours.mcap"
    with McapRecorder(path, chunk_size_bytes=4096, epoch_ns=EPOCH_NS) as recorder:
        _record_run(recorder, 300)
        recorder.add_attachment("model.xml", "application/xml", b"<mujoco/>", t_s=0.5)
    theirs = io.BytesIO()
    writer = Writer(theirs, chunk_size=4096, compression=CompressionType.ZSTD)
    writer.start(profile="", library="x")
    ids = {}
    for topic in TOPICS:
        schema = json.dumps({"title": f"test{topic.replace('/', '.')}", "type": "object"})
        ids[topic] = writer.register_channel(topic, "json", writer.register_schema(
            f"test{topic.replace('/', '.')}", "jsonschema", schema.encode()))
    writer.add_metadata("run", {"epoch_ns": str(EPOCH_NS)})
    for i in range(300):
        log_time = EPOCH_NS + round(i * 0.002 * 1e9)
        writer.add_message(ids[TOPICS[i % 3]], log_time,
                           json.dumps({"i": i, "values": [i * 0.5] * 20},
                                      separators=(",", ":")).encode(),
                           log_time, i // 3)
    writer.add_attachment(EPOCH_NS + 500_000_000, EPOCH_NS + 500_000_000, "model.xml",
                          "application/xml", b"<mujoco/>")
    writer.finish()

    def content(stream: Any) -> dict[str, Any]:
        reader = make_reader(stream, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        statistics = summary.statistics
        return {
            "messages": [(c.topic, m.log_time, m.publish_time, m.sequence, m.data)
                         for _, c, m in reader.iter_messages(log_time_order=False)],
            "channels": [(c.id, c.topic, c.schema_id, c.message_encoding)
                         for c in summary.channels.values()],
            "schemas": [(s.id, s.name, s.encoding, s.data) for s in summary.schemas.values()],
            "metadata": [(m.name, m.metadata) for m in reader.iter_metadata()],
            "attachments": [(a.name, a.media_type, a.log_time, a.create_time, a.data)
                            for a in reader.iter_attachments()],
            "statistics": (statistics.message_count, dict(statistics.channel_message_counts),
                           statistics.message_start_time, statistics.message_end_time,
                           statistics.chunk_count > 1),
        }

    with open(path, "rb") as ours:
        assert content(ours) == content(io.BytesIO(theirs.getvalue()))


def test_a_run_cut_short_keeps_every_complete_chunk(tmp_path: Path) -> None:
    """What is on disk while the recorder is still writing (what a killed process leaves):
    every message of every finished chunk, for mcap's streaming reader and cosim's."""
    path = tmp_path / "cut.mcap"
    snapshot = tmp_path / "snapshot.mcap"
    recorder = McapRecorder(path, chunk_size_bytes=4096, epoch_ns=EPOCH_NS)
    with recorder:
        recorder.publish()
        _record_run(recorder, 500)
        snapshot.write_bytes(path.read_bytes())  # the process would be killed here
        for i in range(10):
            recorder.write(TOPICS[0], 2.0 + i * 0.002, {"i": i})
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None
        cut = snapshot.stat().st_size
        complete = [index for index in summary.chunk_indexes
                    if index.chunk_start_offset + index.chunk_length
                    + index.message_index_length <= cut]
        every = [(m.channel_id, m.log_time, m.sequence, m.data)
                 for _, _, m in reader.iter_messages(log_time_order=False)]
    in_complete = sum(len(r.records) for r in _message_indexes(path, complete))
    assert len(complete) >= 3 and 0 < in_complete < 500
    expected = every[:in_complete]

    def streamed(data: bytes) -> list[tuple]:
        found = []
        with pytest.raises((McapError, EOFError, struct.error, zstandard.ZstdError)):
            for record in StreamReader(io.BytesIO(data)).records:
                if isinstance(record, Message):
                    found.append((record.channel_id, record.log_time, record.sequence,
                                  record.data))
        return found

    assert streamed(snapshot.read_bytes()) == expected
    # cut again inside the next chunk: the same messages, nothing half-read
    whole = path.read_bytes()
    next_chunk = summary.chunk_indexes[len(complete)]
    assert streamed(whole[:next_chunk.chunk_start_offset + next_chunk.chunk_length // 2]) == (
        expected)
    logged = read_summary(snapshot)
    assert logged.truncated and logged.message_count == in_complete


def _message_indexes(path: Path, chunk_indexes: list[Any]) -> list[MessageIndex]:
    data = path.read_bytes()
    indexes = []
    for chunk_index in chunk_indexes:
        for offset in chunk_index.message_index_offsets.values():
            (length,) = struct.unpack_from("<Q", data, offset + 1)
            indexes.append(MessageIndex.read(_stream(io.BytesIO(data[offset + 9:offset + 9
                                                                     + length]))))
    return indexes


def test_recorder_sequences_and_times(tmp_path: Path) -> None:
    path = tmp_path / "times.mcap"
    with McapRecorder(path, epoch_ns=EPOCH_NS) as recorder:
        _record_run(recorder, 30)
    with open(path, "rb") as stream:
        read = [(c.topic, m.sequence, m.log_time, m.publish_time)
                for _, c, m in make_reader(stream).iter_messages(log_time_order=False)]
    assert read == [(TOPICS[i % 3], i // 3, EPOCH_NS + i * 2_000_000, EPOCH_NS + i * 2_000_000)
                    for i in range(30)]
