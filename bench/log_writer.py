"""The log writer's cost: the ``mcap`` package's Writer against :mod:`cosim.log.mcap_writer`,
and the zstd level of the chunks.

    .venv/bin/python bench/log_writer.py [--repeats 5] [--levels -5 -1 1 2 3] [--duration S]

One default lane change (every default, full logging) is run once with its recorder's
writer wrapped, so that every call the recorder makes (schemas, channels, metadata,
messages, attachments) is kept. The calls are then replayed, ``--repeats`` times each, into
a temporary file through the recorder's flushing stream:

1. **Per message**: the whole replay (every record, compression, CRCs, the summary) over
   the number of messages, for ``mcap.writer.Writer`` (zstd at its default level, 3, as
   the recorder used it) and for :class:`~cosim.log.mcap_writer.McapWriter` at level 3 and
   at the level the recorder uses; and the same less the time zstd takes on that run's
   chunks (what is left is building the records in Python).
2. **zstd levels**: for each of ``--levels``, the time zstd takes to compress the run's
   chunks (their uncompressed records, as the writer hands them to zstd) and the file's
   size.
3. **Same content**: the files of both writers decoded with the ``mcap`` package's readers
   (the indexed reader's messages, summary, metadata and attachments; the streaming
   reader's records): identical messages (topic, log and publish time, sequence, data),
   channels, schemas, metadata and attachments, or the bench stops with what differs.

Times are medians of the repeats in this process; the load (``os.getloadavg``) is printed
at the top. Figures compare with each other, not across machines or moments.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import zstandard
from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from cosim.log import recorder as recorder_module
from cosim.log.mcap_writer import DEFAULT_ZSTD_LEVEL, McapWriter
from cosim.simulation import runner
from cosim.simulation.scenario_config import load_config

Call = tuple[str, tuple[Any, ...]]
"""One writer call: the method's name and its arguments, in
:class:`~cosim.log.mcap_writer.McapWriter`'s order."""


class _CapturingWriter:
    """A :class:`McapWriter` that also keeps every call made to it."""

    def __init__(self, writer: McapWriter, calls: list[Call]) -> None:
        self._writer = writer
        self._calls = calls

    def __getattr__(self, name: str) -> Callable[..., Any]:
        method = getattr(self._writer, name)

        def call(*args: Any, **kwargs: Any) -> Any:
            if kwargs:  # add_attachment's times
                args = (*args, kwargs["log_time"], kwargs.get("create_time", 0))
            self._calls.append((name, args))
            return method(*args)

        return call


def capture_run(duration_s: float | None) -> list[Call]:
    """The writer calls of one default lane change."""
    calls: list[Call] = []
    original = runner.McapRecorder

    class CapturingRecorder(original):  # type: ignore[misc, valid-type]
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self._writer = _CapturingWriter(self._writer, calls)  # type: ignore[assignment]

    runner.McapRecorder = CapturingRecorder  # type: ignore[misc]
    try:
        with tempfile.TemporaryDirectory() as tmp:
            config = load_config("lane-change", duration_s=duration_s)
            runner.run(config, Path(tmp) / "captured.mcap")
    finally:
        runner.McapRecorder = original  # type: ignore[misc]
    return calls


class _OldWriter:
    """``mcap.writer.Writer`` behind :class:`McapWriter`'s methods, used as the recorder
    used it before (zstd at the ``zstandard`` package's default level, 3)."""

    def __init__(self, stream: Any, chunk_size: int, library: str) -> None:
        self._writer = Writer(stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library=library)

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        return self._writer.register_schema(name=name, encoding=encoding, data=data)

    def add_channel(self, topic: str, message_encoding: str, schema_id: int) -> int:
        return self._writer.register_channel(topic=topic, message_encoding=message_encoding,
                                             schema_id=schema_id)

    def add_message(self, channel_id: int, log_time: int, publish_time: int, sequence: int,
                    data: bytes) -> None:
        self._writer.add_message(channel_id=channel_id, log_time=log_time, data=data,
                                 publish_time=publish_time, sequence=sequence)

    def add_metadata(self, name: str, values: Mapping[str, str]) -> None:
        self._writer.add_metadata(name=name, data=dict(values))

    def add_attachment(self, name: str, media_type: str, data: bytes, log_time: int,
                       create_time: int) -> None:
        self._writer.add_attachment(create_time=create_time, log_time=log_time, name=name,
                                    media_type=media_type, data=data)

    def finish(self) -> None:
        self._writer.finish()


def replay(calls: list[Call], path: Path, make: Callable[[Any], Any]) -> float:
    """Seconds to write ``calls`` to ``path`` through the writer ``make(stream)`` builds
    (its construction, which writes the header, included)."""
    with open(path, "wb") as file:
        stream = recorder_module._FlushingStream(file)
        start = time.perf_counter()
        writer = make(stream)
        for name, args in calls:
            getattr(writer, name)(*args)
        writer.finish()
        return time.perf_counter() - start


def chunk_records(path: Path) -> list[bytes]:
    """The uncompressed records of every chunk of an MCAP file."""
    records = []
    with open(path, "rb") as stream:
        for record in StreamReader(stream, emit_chunks=True).records:
            if isinstance(record, Chunk):
                records.append(zstandard.ZstdDecompressor().decompress(
                    record.data, max_output_size=record.uncompressed_size))
    return records


def compress_seconds(chunks: list[bytes], level: int, repeats: int) -> float:
    """Median seconds zstd at ``level`` takes on all of ``chunks``."""
    compressor = zstandard.ZstdCompressor(level=level)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for chunk in chunks:
            compressor.compress(chunk)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def decoded(path: Path) -> dict[str, Any]:
    """Everything a reader sees of a file, for comparison."""
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        messages = [(channel.topic, message.log_time, message.publish_time, message.sequence,
                     message.data) for _, channel, message in reader.iter_messages(
                         log_time_order=False)]
        content = {
            "messages": messages,
            "schemas": [(s.id, s.name, s.encoding, s.data) for s in summary.schemas.values()],
            "channels": [(c.id, c.topic, c.schema_id, c.message_encoding, c.metadata)
                         for c in summary.channels.values()],
            "metadata": [(m.name, m.metadata) for m in reader.iter_metadata()],
            "attachments": [(a.name, a.media_type, a.log_time, a.create_time, a.data)
                            for a in reader.iter_attachments()],
            "counts": (summary.statistics.message_count,
                       dict(summary.statistics.channel_message_counts),
                       summary.statistics.message_start_time,
                       summary.statistics.message_end_time),
        }
    with open(path, "rb") as stream:
        content["streamed"] = [
            (r.channel_id, r.log_time, r.publish_time, r.sequence, r.data)
            for r in StreamReader(stream, validate_crcs=True).records
            if type(r).__name__ == "Message"]
    return content


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--levels", type=int, nargs="+", default=[-5, -1, 1, 2, 3])
    parser.add_argument("--duration", type=float, default=None,
                        help="simulated seconds (default: the scenario's, 15)")
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    calls = capture_run(args.duration)
    n_messages = sum(name == "add_message" for name, _ in calls)
    chunk_size = recorder_module.CHUNK_SIZE_BYTES
    library = "cosim bench"
    with tempfile.TemporaryDirectory() as tmp:
        old_path, new_path = Path(tmp) / "old.mcap", Path(tmp) / "new.mcap"

        def old(stream: Any) -> Any:
            return _OldWriter(stream, chunk_size, library)

        def new(level: int) -> Callable[[Any], Any]:
            def make(stream: Any) -> Any:
                return McapWriter(stream, chunk_size=chunk_size, compression_level=level,
                                  library=library)
            return make

        writers: dict[str, tuple[Callable[[Any], Any], int, Path]] = {
            "mcap.writer.Writer, zstd 3": (old, 3, old_path),
            "McapWriter, zstd 3": (new(3), 3, Path(tmp) / "new3.mcap"),
            f"McapWriter, zstd {DEFAULT_ZSTD_LEVEL} (the recorder's)":
                (new(DEFAULT_ZSTD_LEVEL), DEFAULT_ZSTD_LEVEL, new_path),
        }
        replay(calls, new_path, new(DEFAULT_ZSTD_LEVEL))
        chunks = chunk_records(new_path)
        raw_bytes = sum(len(chunk) for chunk in chunks)
        print(f"a default run: {n_messages} messages, {len(chunks)} chunks, "
              f"{raw_bytes / 1e6:.2f} MB of records before compression")
        levels = sorted(set(args.levels) | {3, DEFAULT_ZSTD_LEVEL})
        compress = {level: compress_seconds(chunks, level, args.repeats) for level in levels}

        print(f"\n1. writer cost per message, median of {args.repeats} replays of the run")
        print(f"   {'writer':44} {'us/message':>10} {'less zstd':>10} {'run total s':>12}")
        for label, (make, level, path) in writers.items():
            seconds = statistics.median(replay(calls, path, make) for _ in range(args.repeats))
            building = seconds - compress[level]
            print(f"   {label:44} {seconds / n_messages * 1e6:10.2f} "
                  f"{building / n_messages * 1e6:10.2f} {seconds:12.3f}")

        print(f"\n2. zstd level: compressing the run's chunks (median of {args.repeats}), "
              "and the file")
        print(f"   {'level':>5} {'compress s/run':>15} {'file MB':>9} {'vs level 3':>11}")
        sizes = {}
        for level in levels:
            path = Path(tmp) / f"level{level}.mcap"
            replay(calls, path, new(level))
            sizes[level] = path.stat().st_size
        for level in levels:
            mark = "  <- the recorder's" if level == DEFAULT_ZSTD_LEVEL else ""
            print(f"   {level:5d} {compress[level]:15.4f} {sizes[level] / 1e6:9.3f} "
                  f"{sizes[level] / sizes[3]:10.2f}x{mark}")

        old_content, new_content = decoded(old_path), decoded(new_path)
        differing = [key for key in old_content if old_content[key] != new_content[key]]
        print("\n3. same content (mcap's indexed and streaming readers): "
              + ("identical" if not differing else f"DIFFERENT: {', '.join(differing)}"))
        print(f"   {len(new_content['messages'])} messages, "
              f"{len(new_content['channels'])} channels, "
              f"{len(new_content['metadata'])} metadata, "
              f"{len(new_content['attachments'])} attachments")
        if differing:
            raise SystemExit(1)
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
