"""The recorder's MCAP files (foxglove-sdk's writer through :mod:`cosim.log.held_chunks`)
read back by the ``mcap`` package.

Every file here is read with mcap's readers, the indexed one (seeking: summary, chunk
indexes, message indexes) and the streaming one (record by record, CRCs validated). The
recorder's files are compared with what mcap's own Writer makes of the same calls, and
what is on disk while a run is still writing (what a killed process leaves) is read as a
reader would read it.
"""

from __future__ import annotations

import io
import json
import struct
from pathlib import Path
from typing import Any

import pytest
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Message, MessageIndex
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from cosim.log.held_chunks import HeldChunks
from cosim.log.reader import read_summary
from cosim.log.recorder import McapRecorder

TOPICS = ("/a", "/b", "/c")
EPOCH_NS = 1_767_225_600_000_000_000


def _stream(data: io.BytesIO) -> ReadDataStream:
    return ReadDataStream(data)


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
                           log_time, i // 3 + 1)  # foxglove-sdk counts from 1
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
    assert read == [(TOPICS[i % 3], i // 3 + 1, EPOCH_NS + i * 2_000_000,
                     EPOCH_NS + i * 2_000_000) for i in range(30)]


def test_a_recorder_file_streams_record_by_record_with_valid_crcs(tmp_path: Path) -> None:
    path = tmp_path / "crc.mcap"
    with McapRecorder(path, chunk_size_bytes=4096, epoch_ns=EPOCH_NS) as recorder:
        recorder.publish()
        _record_run(recorder, 400)
        recorder.add_attachment("model.xml", "application/xml", b"<mujoco/>")
    kinds = [type(r).__name__ for r in StreamReader(io.BytesIO(path.read_bytes()),
                                                    validate_crcs=True).records]
    assert kinds[0] == "Header" and kinds[-1] == "Footer" and kinds.count("ChunkIndex") > 3
    summary = read_summary(path)
    assert not summary.truncated and summary.message_count == 400


def test_an_empty_log_is_valid(tmp_path: Path) -> None:
    path = tmp_path / "empty.mcap"
    with McapRecorder(path) as recorder:
        recorder.register("/quiet", {"title": "Q", "type": "object"})
        recorder.add_metadata("run", {"seed": "0"})
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        summary = reader.get_summary()
        assert [m.name for m in reader.iter_metadata()] == ["run"]
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == 0


def test_an_open_chunk_never_reaches_the_file() -> None:
    """The writer's chunk header with placeholder lengths is held until filled in: at every
    write, the file holds whole records only."""
    import foxglove
    from foxglove.mcap import MCAPWriteOptions

    file = io.BytesIO()
    stream = HeldChunks(file)
    context = foxglove.Context()
    writer = foxglove.open_mcap(stream, context=context,
                                writer_options=MCAPWriteOptions(chunk_size=1000))
    channel = foxglove.Channel("/a", message_encoding="json", context=context)
    sizes = set()
    for i in range(300):
        channel.log(b'{"i": %d}' % i, log_time=i)
        data = file.getvalue()
        sizes.add(len(data))
        offset = 8  # the magic
        while offset < len(data):
            _, length = struct.unpack_from("<BQ", data, offset)
            assert length < 1 << 32, f"a record of {length} bytes at {offset}"
            offset += 9 + length
        assert offset == len(data)
    writer.close()
    assert len(sizes) > 5  # chunks were committed as the writer went


class _FullDisk(io.BytesIO):
    """A file that takes ``room`` bytes, then fails as a full disk does."""

    def __init__(self, room: int) -> None:
        super().__init__()
        self.room = room

    def write(self, data: Any) -> int:
        if self.tell() + len(data) > self.room:
            raise OSError(28, "No space left on device")
        return super().write(data)


def test_a_full_disk_is_kept_for_the_recorder_not_logged_by_the_writer(
        caplog: pytest.LogCaptureFixture) -> None:
    """The writer would log a failed write and carry on: the stream keeps the error (the
    recorder raises it at its next message) and writes nothing after it."""
    import foxglove
    from foxglove.mcap import MCAPWriteOptions

    file = _FullDisk(room=3000)
    stream = HeldChunks(file)
    context = foxglove.Context()
    writer = foxglove.open_mcap(stream, context=context,
                                writer_options=MCAPWriteOptions(chunk_size=1000))
    channel = foxglove.Channel("/a", message_encoding="json", context=context)
    for i in range(400):
        channel.log(b'{"i": %d, "pad": "%s"}' % (i, b"x" * 40), log_time=i)
    writer.close()
    assert isinstance(stream.error, OSError) and stream.error.errno == 28
    assert 0 < len(file.getvalue()) <= 3000
    assert not [r for r in caplog.records if r.name.startswith("foxglove")]
