"""The log writer's cost: foxglove-sdk's MCAP writer (the recorder's) against the ``mcap``
package's Writer, and the zstd level of the chunks.

    .venv/bin/python bench/log_writer.py [--repeats 5] [--levels 1 3] [--duration S]

One default lane change (every default, full logging) is run once and its log read back
with the ``mcap`` package's reader: every channel and message as written (topic, schema,
log time, JSON bytes). The messages are then replayed,
``--repeats`` times each, into a temporary file:

- ``mcap.writer.Writer``, zstd at its default level (3);
- foxglove-sdk's writer (``foxglove.open_mcap``) through :class:`cosim.log.held_chunks.HeldChunks`
  (the recorder's path to the file), at each of ``--levels``.

Printed: the median time per message (the whole replay, summary included, over the number
of messages) and the file's size. Every file is read back with the ``mcap`` package's
indexed reader and must hold the same messages, or the bench stops with what differs.
Times are medians of the repeats in this process; the load (``os.getloadavg``) is printed
at the top. Figures compare with each other, not across machines or moments.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
import time
import warnings
from pathlib import Path

import foxglove
from foxglove.mcap import MCAPCompression, MCAPWriteOptions
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from cosim.log.held_chunks import HeldChunks
from cosim.log.recorder import CHUNK_SIZE_BYTES, ZSTD_LEVEL
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config


@dataclasses.dataclass
class _Kept:
    """Every channel and message of a run's log, in the order written."""

    channels: dict[str, tuple[str, bytes]] = dataclasses.field(default_factory=dict)
    messages: list[tuple[str, int, bytes]] = dataclasses.field(default_factory=list)

    @classmethod
    def read(cls, path: Path) -> _Kept:
        kept = cls()
        with open(path, "rb") as file:
            for schema, channel, message in make_reader(file).iter_messages(
                    log_time_order=False):
                kept.channels.setdefault(channel.topic, (schema.name, schema.data))
                kept.messages.append((channel.topic, message.log_time, message.data))
        return kept


def _with_mcap(kept: _Kept, path: Path) -> None:
    with open(path, "wb") as file:
        writer = Writer(file, chunk_size=CHUNK_SIZE_BYTES, compression=CompressionType.ZSTD)
        writer.start(profile="", library="bench")
        ids = {topic: writer.register_channel(topic, "json", writer.register_schema(
            name, "jsonschema", schema)) for topic, (name, schema) in kept.channels.items()}
        sequence = dict.fromkeys(ids, 0)
        for topic, log_time, data in kept.messages:
            sequence[topic] += 1
            writer.add_message(ids[topic], log_time, data, log_time, sequence[topic])
        writer.finish()


def _with_foxglove(kept: _Kept, path: Path, level: int) -> None:
    with open(path, "wb") as file:
        stream = HeldChunks(file)
        context = foxglove.Context()
        writer = foxglove.open_mcap(stream, context=context, writer_options=MCAPWriteOptions(
            compression=MCAPCompression.Zstd, compression_level=level,
            chunk_size=CHUNK_SIZE_BYTES, profile="", compression_threads=0))
        channels = {topic: foxglove.Channel(
            topic, schema=foxglove.Schema(name=name, encoding="jsonschema", data=schema),
            message_encoding="json", context=context)
            for topic, (name, schema) in kept.channels.items()}
        for topic, log_time, data in kept.messages:
            channels[topic].log(data, log_time=log_time)
        writer.close()
        stream.commit()


def _messages(path: Path) -> list[tuple[str, int, bytes]]:
    with open(path, "rb") as file:
        return [(channel.topic, message.log_time, message.data)
                for _, channel, message in make_reader(file).iter_messages(
                    log_time_order=False)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--levels", type=int, nargs="+", default=[ZSTD_LEVEL, 3])
    parser.add_argument("--duration", type=float, default=15.0)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}")
    config = load_config("lane-change", overrides=[f"sim.duration_s={args.duration}"])
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run(config, Path(tmp) / "run.mcap")
        kept = _Kept.read(Path(tmp) / "run.mcap")
        n = len(kept.messages)
        print(f"{n} messages of a {args.duration:g} s lane change\n")
        writers = {"mcap.writer.Writer, zstd 3": lambda p: _with_mcap(kept, p)}
        for level in args.levels:
            mark = " (the recorder's)" if level == ZSTD_LEVEL else ""
            writers[f"foxglove-sdk, zstd {level}{mark}"] = \
                lambda p, level=level: _with_foxglove(kept, p, level)
        expected = list(kept.messages)
        print(f"{'writer':36s} {'us/message':>11s} {'file MB':>8s}")
        for name, write in writers.items():
            path = Path(tmp) / "replay.mcap"
            times = []
            for _ in range(args.repeats):
                path.unlink(missing_ok=True)
                start = time.perf_counter()
                write(path)
                times.append(time.perf_counter() - start)
            if _messages(path) != expected:
                raise SystemExit(f"{name}: the file's messages differ from the run's")
            print(f"{name:36s} {statistics.median(times) / n * 1e6:11.2f} "
                  f"{path.stat().st_size / 1e6:8.2f}")


if __name__ == "__main__":
    main()
