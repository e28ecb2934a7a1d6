"""A run's log written by another process: the run encodes its messages and sends them
through a pipe; the process at the other end writes the MCAP file.

``cosim run`` runs the simulation in a child process its parent watches
(:mod:`cosim.cli.guard`). The parent only waits, on a core of its own, while the child
spent a tenth of its loop in foxglove-sdk's ``Channel.log`` and the zstd compression of the
chunks, which hold the GIL: no thread of the child could take them off its loop. So the
child's recorder is a :class:`PipedRecorder`: it encodes each message (orjson, as
:class:`~cosim.log.recorder.McapRecorder` does) and appends it to a buffer sent down a pipe
every :data:`FLUSH_BYTES`; the parent's :class:`LogServer` takes each frame to an
:class:`~cosim.log.recorder.McapRecorder` of its own. The file holds the same records in the
same order as when the child writes it itself: every MCAP reader reads it the same.

Frames: a header (:data:`HEADER`: the operation, the payload's length, a channel number and
a log time in ns) and the payload. The operations that must have happened before the run
goes on (:data:`OPEN`, which can refuse the path; :data:`PUBLISH`, after which the log has
its final name; :data:`CLOSE`, :data:`ABANDON`) wait for the server's one-line answer on a
second pipe: ``ok``, or the error to raise in the child (:class:`ConfigError`, an
``OSError`` with its ``errno``). A write that fails in the server (a full disk) is answered
at once; the child raises it at its next flush, as ``McapRecorder.write`` raises a failed
write at its next message, so the run ends with one line and what reached the disk stays
readable.

A child that dies (a segmentation fault in a plug-in, ``SIGKILL``) closes the pipe with its
process: the server then finishes the log with what it received, the MCAP summary
included (:meth:`LogServer.finish`); a log not yet published is removed, as
:meth:`McapRecorder.abandon` removes it.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import pickle
import select
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cosim.core.exceptions import ConfigError
from cosim.core.interrupts import interrupts_held

if TYPE_CHECKING:
    from cosim.log.packed_records import PackedReader
    from cosim.log.recorder import McapRecorder
    from cosim.log.run_messages import MessageContext, RunMessageSink

OPEN, REGISTER, WRITE, METADATA, ATTACH, PUBLISH, CLOSE, ABANDON, CONTEXT, PACKED = range(1, 11)
"""The frames' operations (:data:`CONTEXT` and :data:`PACKED`: the run's most frequent
records as numbers, :mod:`cosim.log.packed_records`, the messages built by the server)."""
HEADER = struct.Struct("<BIHq")
"""A frame's header: operation, payload bytes, channel number, log time [ns since the
Unix epoch] (the last two for :data:`WRITE`; :data:`REGISTER` numbers its channel,
:data:`PACKED` names the record's kind there)."""
FLUSH_BYTES = 64 * 1024
"""The child sends its buffer when it holds this much (some 40 messages of a default run;
about 270 writes to the pipe a run)."""
PIPE_BYTES = 1024 * 1024
"""The pipe's capacity asked of Linux (``F_SETPIPE_SZ``): a second of a default run's
messages, so that the child does not wait on the server when a chunk is compressed."""
F_SETPIPE_SZ = 1031
"""``fcntl(2)`` on Linux."""


@dataclass(frozen=True)
class LogLink:
    """One side's ends of the two pipes: the run's write frames and read answers, the
    server's read frames and write answers."""

    frames_fd: int
    answers_fd: int


def log_pipes() -> tuple[LogLink, LogLink]:
    """Two pipes: the run's ends and the server's."""
    frames_read, frames_write = os.pipe()
    answers_read, answers_write = os.pipe()
    with contextlib.suppress(OSError, AttributeError):
        import fcntl

        fcntl.fcntl(frames_write, F_SETPIPE_SZ, PIPE_BYTES)
    return LogLink(frames_write, answers_read), LogLink(frames_read, answers_write)


class PipedRecorder:
    """A :class:`~cosim.log.recorder.Recorder` that sends the log to a :class:`LogServer`
    (module docstring). Use as a context manager, as :class:`McapRecorder`."""

    keeps = True

    def __init__(self, link: LogLink, path: Path, epoch_ns: int = 0) -> None:
        from cosim.log.recorder import encode_message, seconds_to_ns

        self._encode, self._ns = encode_message, seconds_to_ns  # imported with foxglove-sdk
        self.path = Path(path)
        self.epoch_ns = epoch_ns
        self._link = link
        self._buffer = bytearray()
        self._channels: dict[str, int] = {}
        self._published = False
        self._closed = False
        self._request(OPEN, os.fsencode(self.path), log_time_ns=epoch_ns)

    def __enter__(self) -> PipedRecorder:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc_info: object) -> None:
        if exc_type is not None and not self._published:
            self.abandon()
        else:
            self.close()

    def register(self, topic: str, schema: Mapping[str, Any] | None = None) -> None:
        """Declare a topic (by default with the schema :mod:`cosim.log.topics` gives it)."""
        if schema is None:
            from cosim.log import topics

            schema = topics.schema_of(topic)
        channel = len(self._channels)
        self._channels[topic] = channel
        self._frame(REGISTER, json.dumps({"topic": topic, "schema": schema}).encode(),
                    channel=channel)

    def write(self, topic: str, t_s: float, message: dict[str, Any]) -> None:
        """One message at simulated time ``t_s`` (NaN and inf are written as null)."""
        data = self._encode(message)
        buffer = self._buffer
        buffer += HEADER.pack(WRITE, len(data), self._channels[topic],
                              self.epoch_ns + self._ns(t_s))
        buffer += data
        if len(buffer) >= FLUSH_BYTES:
            self._flush()

    write_finite = write
    """:meth:`write`, named for the messages that may carry NaN or inf (written as null)."""

    def messages(self, context: MessageContext) -> RunMessageSink:
        """The run's most frequent records sent as numbers (:mod:`cosim.log.packed_records`):
        the server builds their messages, on its own core, with ``context``."""
        from cosim.log.packed_records import PackedMessages
        from cosim.log.run_messages import RunMessages

        self._frame(CONTEXT, pickle.dumps(context, protocol=pickle.HIGHEST_PROTOCOL))
        return PackedMessages(self._packed, RunMessages(self, context))

    def _packed(self, kind: int, payload: bytes) -> None:
        self._frame(PACKED, payload, channel=kind)

    def add_metadata(self, name: str, values: dict[str, str]) -> None:
        self._frame(METADATA, json.dumps({"name": name, "values": values}).encode())

    def add_attachment(self, name: str, media_type: str, data: bytes, t_s: float = 0.0) -> None:
        described = json.dumps({"name": name, "media_type": media_type}).encode()
        self._frame(ATTACH, described + b"\n" + data,
                    log_time_ns=self.epoch_ns + self._ns(t_s))

    def publish(self) -> None:
        """The log takes its final name, its header and first messages in a complete chunk
        (:meth:`McapRecorder.publish`, in the server); idempotent."""
        if not self._published:
            self._request(PUBLISH)
            self._published = True

    def close(self) -> None:
        """The server writes the summary, publishes and closes the file (idempotent)."""
        if not self._closed:
            self._closed = True
            self._request(CLOSE)

    def abandon(self) -> None:
        """Close without finishing and remove the unpublished file (idempotent; a failure
        of the server is not raised over the error that abandons the log)."""
        if not self._closed:
            self._closed = True
            with contextlib.suppress(OSError):
                self._request(ABANDON)

    def _frame(self, operation: int, payload: bytes, channel: int = 0,
               log_time_ns: int = 0) -> None:
        self._buffer += HEADER.pack(operation, len(payload), channel, log_time_ns)
        self._buffer += payload
        if len(self._buffer) >= FLUSH_BYTES:
            self._flush()

    def _flush(self, check: bool = True) -> None:
        """Send the buffer; first (``check``) raise a failure the server has reported."""
        answers = self._link.answers_fd
        if check and select.select([answers], [], [], 0.0)[0]:
            tag, _, failure = _read_line(answers).partition(" ")
            raise _error(failure if tag == FAILED else "")
        view = memoryview(self._buffer)
        try:
            while view:
                view = view[os.write(self._link.frames_fd, view):]
        except BrokenPipeError:
            raise _error("") from None
        finally:
            view.release()
        self._buffer.clear()

    def _request(self, operation: int, payload: bytes = b"", log_time_ns: int = 0) -> None:
        """A frame whose answer the run waits for: raise a failure the server reported
        before it (a write's), else the request's own. An interrupt during the exchange is
        raised when its answer is in (:func:`cosim.core.interrupts.interrupts_held`), so the
        next request reads its own answer, not the rest of this one's."""
        with interrupts_held():
            self._frame(operation, payload, log_time_ns=log_time_ns)
            self._flush(check=False)
            failure = None
            while True:
                tag, _, text = _read_line(self._link.answers_fd).partition(" ")
                if tag == FAILED:
                    failure = failure if failure is not None else text
                    continue
                break
        if failure is not None:
            raise _error(failure)
        if tag != ANSWER:
            raise _error("")
        if text != OK:
            raise _error(text)


FAILED, ANSWER, OK = "failed", "answer", "ok"
"""The server's lines: ``failed <failure>`` at once when an operation the run does not
wait for fails (nothing is written after it), ``answer ok`` or ``answer <failure>`` for
each request; a failure is ``config <message>``, ``oserror <errno> <message>`` or
``error <message>``."""


def _read_line(descriptor: int) -> str:
    """One line from the server (blocking); an empty string when it has gone."""
    line = b""
    while not line.endswith(b"\n"):
        data = os.read(descriptor, 1)
        if not data:
            return ""
        line += data
    return line[:-1].decode(errors="surrogateescape")


def _error(failure: str) -> Exception:
    """The exception a failure line stands for (an empty one: the server has gone)."""
    kind, _, text = failure.partition(" ")
    if kind == "config":
        return ConfigError(text)
    if kind == "oserror":
        number, _, message = text.partition(" ")
        return OSError(int(number) if number.lstrip("-").isdigit() else errno.EIO, message)
    return OSError(errno.EIO, text or "the process writing the log has ended")


class LogServer:
    """The other end of a :class:`PipedRecorder`: applies its frames to an
    :class:`McapRecorder` (module docstring)."""

    def __init__(self, ends: LogLink) -> None:
        # Imported now, while the run starts on the other core, not when it waits for the
        # answer to its first request: foxglove-sdk, and numpy with the messages' code.
        from cosim.log.packed_records import PackedReader
        from cosim.log.recorder import McapRecorder
        from cosim.log.run_messages import RunMessages

        self._open_recorder = McapRecorder
        self._packed_reader, self._run_messages = PackedReader, RunMessages
        self._ends = ends
        self._buffer = bytearray()
        self._recorder: McapRecorder | None = None
        self._topics: list[str] = []
        self._packed: PackedReader | None = None
        """Builds the messages of the packed records (from the run's :data:`CONTEXT`)."""
        self._failure: str | None = None
        """The answer line of the first failure (nothing is written after it)."""
        self._done = False
        """The recorder was closed or abandoned."""

    def feed(self, data: bytes) -> None:
        """Apply every complete frame of ``data`` (with what an earlier call left)."""
        buffer = self._buffer
        buffer += data
        offset, end_of_data, size = 0, len(buffer), HEADER.size
        while end_of_data - offset >= size:
            operation, length, channel, log_time_ns = HEADER.unpack_from(buffer, offset)
            end = offset + size + length
            if end > end_of_data:
                break
            payload = bytes(buffer[offset + size:end])
            offset = end
            if operation == WRITE:
                if self._failure is None and self._recorder is not None:
                    try:
                        self._recorder.write_encoded(self._topics[channel], log_time_ns,
                                                     payload)
                    except Exception as error:  # noqa: BLE001 - raised in the run
                        self._fail(_failure_text(error))
            elif operation == PACKED:
                if self._failure is None and self._packed is not None and not self._done:
                    try:
                        self._packed.apply(channel, payload)
                    except Exception as error:  # noqa: BLE001 - raised in the run
                        self._fail(_failure_text(error))
            else:
                self._control(operation, channel, log_time_ns, payload)
        del buffer[:offset]

    def finish(self) -> None:
        """The child has gone: finish its log with what arrived (the summary included) if
        it was published, remove it otherwise."""
        recorder = self._recorder
        if recorder is None or self._done:
            return
        self._done = True
        with contextlib.suppress(Exception):
            if recorder.published:
                recorder.close()
            else:
                recorder.abandon()

    def _control(self, operation: int, channel: int, log_time_ns: int,
                 payload: bytes) -> None:
        if operation == OPEN:
            self._answer(_failure_of(self._open, payload, log_time_ns))
            return
        recorder = self._recorder
        if recorder is None or self._done:  # refused, or closed: a request still answered
            if operation in (PUBLISH, CLOSE, ABANDON):
                self._answer(self._failure or "error the log is not open")
            return
        if operation == REGISTER:
            described = json.loads(payload)
            self._topics[channel:channel + 1] = [described["topic"]]
            self._noted(recorder.register, described["topic"], described["schema"])
        elif operation == CONTEXT:
            self._packed = self._packed_reader(self._run_messages(recorder,
                                                                  pickle.loads(payload)))
        elif operation == METADATA:
            described = json.loads(payload)
            self._noted(recorder.add_metadata, described["name"], described["values"])
        elif operation == ATTACH:
            head, _, data = payload.partition(b"\n")
            described = json.loads(head)
            self._noted(recorder.add_attachment_at, described["name"],
                        described["media_type"], data, log_time_ns)
        elif operation == PUBLISH:
            self._answer(self._failure or _failure_of(recorder.publish))
        elif operation in (CLOSE, ABANDON):
            self._done = True
            self._answer(_failure_of(recorder.close if operation == CLOSE
                                     else recorder.abandon))

    def _open(self, payload: bytes, epoch_ns: int) -> None:
        self._recorder = self._open_recorder(Path(os.fsdecode(payload)), epoch_ns=epoch_ns)

    def _noted(self, action: Callable[..., None], *arguments: Any) -> None:
        """Run an operation the run does not wait for, unless one failed before; its
        failure is sent at once and stops every later one."""
        if self._failure is None:
            failure = _failure_of(action, *arguments)
            if failure is not None:
                self._fail(failure)

    def _fail(self, failure: str) -> None:
        self._failure = failure
        self._send(f"{FAILED} {failure}")

    def _answer(self, failure: str | None) -> None:
        self._send(f"{ANSWER} {failure if failure is not None else OK}")

    def _send(self, line: str) -> None:
        with contextlib.suppress(OSError):  # the child has gone: nobody to tell
            os.write(self._ends.answers_fd, f"{line}\n".encode(errors="surrogateescape"))


def _failure_of(action: Callable[..., None], *arguments: Any) -> str | None:
    """Run ``action``: None, or its failure as the server's lines carry it."""
    try:
        action(*arguments)
    except Exception as error:  # noqa: BLE001 - raised in the run, not in the server
        return _failure_text(error)
    return None


def _failure_text(error: Exception) -> str:
    if isinstance(error, ConfigError):
        return f"config {error}"
    if isinstance(error, OSError):
        return f"oserror {error.errno} {error.strerror or error}"
    return f"error {type(error).__name__}: {error}"
