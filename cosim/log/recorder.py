"""MCAP recorder: one JSON channel per topic, each with a JSON schema; chunked and compressed.

Messages are encoded with orjson (a compiled encoder, 5-10x faster than :mod:`json` on these
messages, with the same output: compact separators, shortest round-trip floats), numpy
scalars and arrays included; NaN and infinity, which JSON cannot represent, become null.

Log time is integer nanoseconds since the Unix epoch: the run's ``sim.epoch`` plus its
simulated time. The file is written by foxglove-sdk's MCAP writer (``foxglove.open_mcap``:
the Rust ``mcap`` crate, by the MCAP authors), a sink of channels on a
:class:`foxglove.Context` of the recorder's own, so nothing else logged in the process
reaches the file; its per-message cost is about a microsecond (``bench/log_writer.py``).
``cosim run --live`` adds Foxglove's WebSocket server as a second sink on the same context
(:class:`LiveSink`): the file and the live view get each message from one ``Channel.log``.
It writes through :class:`cosim.log.held_chunks.HeldChunks`, which lets only finished
records reach the file, so a killed process loses at most the chunk being filled (about
``chunk_size_bytes`` of data, a second or so of a run) and leaves a log every MCAP
reader reads.

Chunks are zstd-compressed at level 1 (:data:`ZSTD_LEVEL`), chosen from the figures of
``bench/log_writer.py``: on a default run's messages it takes well under the time of
zstd's default level 3 and gives a file no larger.

The chunk size also sets the recorder's memory growth: MCAP's summary section indexes every
chunk, so the writer keeps one Chunk Index record per chunk until the file is finished
(``bench/long_run.py`` measures the growth over an hour-long run); larger chunks, fewer
indexes.

The file is written under a temporary name and renamed to its final name by
:meth:`McapRecorder.publish` (see :mod:`cosim.log.safe_file`): a run refused before it
publishes leaves the final name untouched.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import foxglove
import orjson
from foxglove.mcap import MCAPCompression, MCAPWriteOptions

from cosim.core.exceptions import ConfigError
from cosim.log.held_chunks import HeldChunks
from cosim.log.safe_file import PendingFile

if TYPE_CHECKING:
    from cosim.log.run_messages import MessageContext, RunMessageSink


def seconds_to_ns(t_s: float) -> int:
    """Simulated seconds to integer nanoseconds (rounded, so 0.002 s -> 2_000_000 ns)."""
    return round(t_s * 1e9)


_ORJSON_OPTIONS = orjson.OPT_SERIALIZE_NUMPY


def encode_message(message: dict[str, Any]) -> bytes:
    """One message as compact JSON bytes; NaN and infinity become null."""
    return orjson.dumps(message, option=_ORJSON_OPTIONS)


LIVE_ONLY = "cosim.live_only"
"""Channel metadata key of a channel the file does not take: a live sink's own channel for
a topic it sends again to late clients (:class:`LiveSink`)."""


def _filed(channel: foxglove.ChannelDescriptor) -> bool:
    """The file's channel filter: every channel of the recorder's context but a live sink's
    own (called once per channel, when it is created)."""
    return LIVE_ONLY not in channel.metadata


class LiveSink(Protocol):
    """A second sink on the recorder's channels (``cosim run --live``:
    :class:`cosim.log.live.LiveStream`, a Foxglove WebSocket server on the recorder's
    context). The file and the sink get the same channels and each message from one
    ``Channel.log``; the sink is told around it, so that it can pace the run and start its
    server when the header's channels exist. It observes only.

    A sink may create channels of its own on the context (a topic it sends again to clients
    that subscribe late); it marks them with the metadata key :data:`LIVE_ONLY`, which the
    file's channel filter leaves out.
    """

    def attach(self, context: foxglove.Context) -> None:
        """The recorder's context, before its first channel."""

    def registered(self, topic: str, schema: foxglove.Schema) -> None:
        """A channel of the log: its topic and schema (as in the file)."""

    def due(self, log_time_ns: int) -> None:
        """A message of this log time is about to be logged on every sink."""

    def sent(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """A message was logged: its topic, log time and JSON bytes (as in the file)."""


class Recorder(Protocol):
    """What the run writes its log through (:class:`McapRecorder`; :class:`NoLog` for a
    run without a log: a sweep's that keeps none, a Gymnasium episode without ``log_dir``)."""

    keeps: bool
    """Whether anything written is kept: when not, the run builds no messages at all."""

    def register(self, topic: str, schema: Mapping[str, Any] | None = None) -> None:
        """Declare a topic (by default with the schema :mod:`cosim.log.topics` gives it)."""

    def write(self, topic: str, t_s: float, message: dict[str, Any]) -> None:
        """One message at simulated time ``t_s``."""

    def write_finite(self, topic: str, t_s: float, message: dict[str, Any]) -> None:
        """:meth:`write`, for messages that may carry NaN or infinity (written as null)."""

    def add_metadata(self, name: str, values: dict[str, str]) -> None: ...

    def add_attachment(self, name: str, media_type: str, data: bytes,
                       t_s: float = 0.0) -> None: ...

    def publish(self) -> None:
        """The run starts for real: the log takes its final name."""

    def messages(self, context: MessageContext) -> RunMessageSink:
        """Where the run's most frequent records go (:mod:`cosim.log.run_messages`)."""


CHUNK_SIZE_BYTES = 1024 * 1024
"""Uncompressed bytes per MCAP chunk: about a second of the default lane change."""
ZSTD_LEVEL = 1
"""The chunks' zstd level (module docstring)."""


class NoLog:
    """A recorder that keeps nothing (:class:`Recorder`)."""

    keeps = False

    def register(self, topic: str, schema: Mapping[str, Any] | None = None) -> None: ...
    def write(self, topic: str, t_s: float, message: dict[str, Any]) -> None: ...
    def write_finite(self, topic: str, t_s: float, message: dict[str, Any]) -> None: ...
    def add_metadata(self, name: str, values: dict[str, str]) -> None: ...
    def add_attachment(self, name: str, media_type: str, data: bytes,
                       t_s: float = 0.0) -> None: ...
    def publish(self) -> None: ...
    def close(self) -> None: ...

    def messages(self, context: MessageContext) -> RunMessageSink:
        from cosim.log.run_messages import RunMessages

        return RunMessages(self, context)


class McapRecorder:
    """Writes a run to an MCAP file. Use as a context manager; it always finishes the file."""

    keeps = True

    def __init__(self, path: Path, chunk_size_bytes: int = CHUNK_SIZE_BYTES,
                 epoch_ns: int = 0, live: LiveSink | None = None) -> None:
        self.path = Path(path)
        self.live = live
        """A second sink on the log's channels (``cosim run --live``), or None."""
        self.epoch_ns = epoch_ns
        """Log time of sim time 0 [ns since the Unix epoch]: every message's and
        attachment's log time is ``epoch_ns`` plus its sim time. Readers subtract it
        (:mod:`cosim.log.reader`, from the ``run`` metadata's ``epoch_ns``)."""
        try:
            self._pending = PendingFile(self.path)
        except OSError as error:
            raise ConfigError(
                f"--out {str(self.path)!r}: cannot write ({error.strerror})"
            ) from None
        self._context = foxglove.Context()
        self._stream = HeldChunks(self._pending.file)
        options = MCAPWriteOptions(compression=MCAPCompression.Zstd,
                                   compression_level=ZSTD_LEVEL, chunk_size=chunk_size_bytes,
                                   profile="", compression_threads=0)
        self._writer = foxglove.open_mcap(self._stream, context=self._context,
                                          writer_options=options, channel_filter=_filed)
        if live is not None:
            live.attach(self._context)
        self._log: dict[str, Callable[[bytes, int], None]] = {}
        """Per topic, its channel's ``log(data, log_time)``."""
        self._closed = False

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc_info: object) -> None:
        if exc_type is not None and not self._pending.published:
            self.abandon()
        else:
            self.close()

    def publish(self) -> None:
        """Put the log at its final name (the run has started for real), its header, channels
        and first messages in a complete chunk (readable whatever happens next); idempotent."""
        if not self._pending.published:
            self._writer.flush()
            self._stream.commit()
        self._pending.publish()

    def abandon(self) -> None:
        """Close without finishing and remove the unpublished file (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self._stream.discard()
        self._writer.close()
        self._pending.close()

    def register(self, topic: str, schema: Mapping[str, Any] | None = None) -> None:
        """Declare a topic with its JSON schema (by default the one :mod:`cosim.log.topics`
        gives it); the schema's title is its name."""
        if schema is None:
            # Imported here: the process that writes ``cosim run``'s log takes the schemas
            # from the run (cosim.log.piped_recorder) and need not import the sensors' models.
            from cosim.log import topics

            schema = topics.schema_of(topic)
        declared = foxglove.Schema(name=schema["title"], encoding="jsonschema",
                                   data=json.dumps(schema).encode())
        channel = foxglove.Channel(topic, schema=declared, message_encoding="json",
                                   context=self._context)
        # The SDK's own ``BaseChannel.log`` (bytes, log time): ``Channel.log`` in Python
        # checks the encoding and the message's type at every call first, a microsecond
        # or two of 17,000 messages a run for bytes this recorder has encoded already.
        self._log[topic] = channel.base.log
        if self.live is not None:
            self.live.registered(topic, declared)

    def write(self, topic: str, t_s: float, message: dict[str, Any]) -> None:
        """Write one message at simulated time ``t_s`` (NaN and inf are written as null)."""
        self.write_encoded(topic, self.epoch_ns + seconds_to_ns(t_s), encode_message(message))

    def write_encoded(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """Write one message already encoded (:func:`encode_message`) at its log time."""
        if self.live is not None:
            self.live.due(log_time_ns)
        self._log[topic](data, log_time_ns)
        if self._stream.error is not None:  # the file could not take a finished chunk
            raise self._stream.error
        if self.live is not None:
            self.live.sent(topic, log_time_ns, data)

    write_finite = write
    """:meth:`write`, named for the messages that may carry NaN or inf (written as null)."""

    def add_metadata(self, name: str, values: dict[str, str]) -> None:
        self._writer.write_metadata(name, values)

    def add_attachment(self, name: str, media_type: str, data: bytes, t_s: float = 0.0) -> None:
        self.add_attachment_at(name, media_type, data, self.epoch_ns + seconds_to_ns(t_s))

    def add_attachment_at(self, name: str, media_type: str, data: bytes,
                          log_time_ns: int) -> None:
        """:meth:`add_attachment` at a log time [ns since the Unix epoch]."""
        self._writer.attach(log_time=log_time_ns, create_time=log_time_ns, name=name,
                            media_type=media_type, data=data)

    def messages(self, context: MessageContext) -> RunMessageSink:
        """The run's most frequent records, their messages built here at once
        (:class:`cosim.log.run_messages.RunMessages`)."""
        from cosim.log.run_messages import RunMessages

        return RunMessages(self, context)

    @property
    def published(self) -> bool:
        """The log has its final name (:meth:`publish`)."""
        return self._pending.published

    def close(self) -> None:
        """Write the summary, publish and close the file (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.close()
            self._stream.commit()
            self._pending.publish()
        finally:
            self._pending.close()
