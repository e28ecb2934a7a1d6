"""cosim.log.reader reads what the ``mcap`` package's own readers read, faster: a chunk's
records split from its fixed headers, a complete file through its chunk indexes, and a
file cut short or damaged up to its last good record."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from cosim.log.reader import _chunk_records, iter_messages, iter_topics, read_attachment

TOPICS = ("/a", "/b", "/c")
MESSAGES = 3000


def _write(path: Path, compression: CompressionType) -> None:
    """A log of three interleaved JSON topics in many small chunks, each message's publish
    time and sequence unlike its log time (so that a field read in another's place shows),
    an attachment and cosim's ``run`` metadata with an epoch."""
    with open(path, "wb") as stream:
        writer = Writer(stream, chunk_size=4096, compression=compression)
        writer.start(profile="", library="test")
        schema = writer.register_schema("number", "jsonschema", b"{}")
        channels = [writer.register_channel(topic, "json", schema) for topic in TOPICS]
        writer.add_metadata("run", {"epoch_ns": "1000"})
        for i in range(MESSAGES):
            writer.add_message(channels[i % 3], log_time=1000 + 10 * i, publish_time=7 * i + 3,
                               sequence=i // 3, data=json.dumps({"i": i}).encode())
        writer.add_attachment(5, 5, "car.xml", "text/xml", b"<mujoco/>")
        writer.finish()


@pytest.fixture(params=[CompressionType.ZSTD, CompressionType.NONE], ids=["zstd", "none"])
def log(request: pytest.FixtureRequest, tmp_path: Path) -> Path:
    path = tmp_path / "log.mcap"
    _write(path, request.param)
    return path


def _chunks(path: Path) -> list[Chunk]:
    with open(path, "rb") as stream:
        return [r for r in StreamReader(stream, emit_chunks=True).records
                if isinstance(r, Chunk)]


def test_a_chunk_splits_into_the_records_mcap_reads(log: Path) -> None:
    chunks = _chunks(log)
    assert len(chunks) > 10
    for chunk in chunks:
        reference = breakup_chunk(chunk)
        assert list(_chunk_records(chunk, None)) == reference
        # Only the wanted channels' messages; every schema and channel record still.
        assert list(_chunk_records(chunk, {2})) == [
            r for r in reference if not isinstance(r, Message) or r.channel_id == 2]


def _reference(path: Path, topics: set[str]) -> list[tuple[str, int, dict]]:
    with open(path, "rb") as stream:
        return [(channel.topic, message.log_time - 1000, json.loads(message.data))
                for _, channel, message in make_reader(stream).iter_messages(
                    topics=sorted(topics), log_time_order=False)]


def test_a_complete_file_gives_the_messages_the_mcap_reader_gives(log: Path) -> None:
    for topics in ({"/b"}, {"/a", "/c"}, set(TOPICS)):
        assert list(iter_topics(log, topics)) == _reference(log, topics)
    assert list(iter_topics(log)) == _reference(log, set(TOPICS))
    assert [m for _, m in iter_messages(log, "/c")] == [
        m for _, _, m in _reference(log, {"/c"})]
    assert read_attachment(log, "car.xml") == b"<mujoco/>"


def test_a_file_cut_short_gives_every_message_before_the_cut(log: Path,
                                                             tmp_path: Path) -> None:
    whole = _reference(log, {"/a", "/b"})
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(log.read_bytes()[:log.stat().st_size // 2])
    read = list(iter_topics(cut, {"/a", "/b"}))
    assert 0.3 * len(whole) < len(read) < 0.7 * len(whole)
    assert read == whole[:len(read)]


def test_a_damaged_chunk_in_a_complete_file_ends_the_messages_there(
        log: Path, tmp_path: Path) -> None:
    chunks = _chunks(log)
    data = bytearray(log.read_bytes())
    # The sixth chunk's first message's record says it runs far past the chunk's end.
    with open(log, "rb") as stream:
        offsets = sorted(i.chunk_start_offset for i in make_reader(stream).get_summary()
                         .chunk_indexes)
    sixth = offsets[5]
    if chunks[5].compression == "":
        records = sixth + 1 + 8 + 8 + 8 + 8 + 4 + 4 + 8  # the chunk's fields before them
        first_message = records
        while data[first_message] != 0x05:  # step over its schema and channel records
            first_message += 9 + int.from_bytes(data[first_message + 1:first_message + 9],
                                                "little")
        data[first_message + 1:first_message + 9] = (10**9).to_bytes(8, "little")
    else:
        middle = sixth + len(chunks[5].data) // 2 + 45
        data[middle:middle + 16] = bytes(16)  # zstd: the frame no longer decompresses
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    before = sum(1 for chunk in chunks[:5] for r in breakup_chunk(chunk)
                 if isinstance(r, Message))
    assert list(iter_topics(damaged)) == _reference(log, set(TOPICS))[:before]
