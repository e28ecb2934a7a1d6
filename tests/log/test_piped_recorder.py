"""A log written by another process (:mod:`cosim.log.piped_recorder`): the same file as the
recorder writing it itself, its failures raised in the run, and a run that dies leaving a
finished log.

The server runs here in a thread of the test's process, reading the same pipes the parent
of ``cosim run`` reads (tests/cli/test_guard.py runs it across the real processes)."""

from __future__ import annotations

import contextlib
import errno
import os
import signal
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from mcap.reader import make_reader

from cosim.core.exceptions import ConfigError
from cosim.log import piped_recorder
from cosim.log.piped_recorder import LogServer, PipedRecorder, log_pipes
from cosim.log.reader import read_summary
from cosim.log.recorder import McapRecorder
from cosim.log.safe_file import partial_path

TOPICS = ("/a", "/b", "/c")
EPOCH_NS = 1_767_225_600_000_000_000


def _record(recorder: McapRecorder | PipedRecorder, n_messages: int) -> None:
    for topic in TOPICS:
        recorder.register(topic, {"title": f"test{topic.replace('/', '.')}", "type": "object"})
    recorder.add_metadata("run", {"epoch_ns": str(EPOCH_NS), "name": "ünïcode"})
    recorder.add_attachment("model.xml", "application/xml", b"<mujoco/>\n\x00", t_s=0.5)
    recorder.publish()
    for i in range(n_messages):
        recorder.write(TOPICS[i % 3], i * 0.002, {"i": i, "values": [i * 0.1] * 50,
                                                  "nan": float("nan")})


@contextlib.contextmanager
def _served() -> Iterator[tuple[piped_recorder.LogLink, LogServer]]:
    """A server reading its pipes in a thread (as ``cosim run``'s parent reads them), until
    the run's end of the frames pipe is closed; then the server finishes."""
    link, ends = log_pipes()
    server = LogServer(ends)

    def serve() -> None:
        while data := os.read(ends.frames_fd, 65536):
            server.feed(data)
        server.finish()

    thread = threading.Thread(target=serve)
    thread.start()
    try:
        yield link, server
    finally:
        os.close(link.frames_fd)  # what the run's process ending does
        thread.join(timeout=60)
        for descriptor in (link.answers_fd, ends.frames_fd, ends.answers_fd):
            os.close(descriptor)


def test_the_served_log_is_the_file_the_recorder_writes_itself(tmp_path: Path) -> None:
    """Every byte equal: the same records in the same order, through more than one flush
    of the pipe (some 30 of them) and more than one chunk."""
    own = tmp_path / "own.mcap"
    with McapRecorder(own, epoch_ns=EPOCH_NS) as recorder:
        _record(recorder, 6000)
    served = tmp_path / "served.mcap"
    with _served() as (link, _), PipedRecorder(link, served, epoch_ns=EPOCH_NS) as recorder:
        _record(recorder, 6000)
    assert served.read_bytes() == own.read_bytes()
    with served.open("rb") as file:
        summary = make_reader(file).get_summary()
    assert summary is not None and summary.statistics.message_count == 6000
    assert summary.statistics.chunk_count > 1


def test_a_path_the_server_cannot_write_is_refused_in_the_run(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    out = blocker / "log.mcap"  # a folder that is a file
    with pytest.raises(ConfigError) as own:
        McapRecorder(out)
    with _served() as (link, _), pytest.raises(ConfigError) as served:
        PipedRecorder(link, out)
    assert str(served.value) == str(own.value)


def test_a_failed_write_is_raised_at_the_runs_next_flush_and_the_log_kept(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A full disk in the server: the run's next send raises the server's error (its
    errno), nothing more is written, closing answers and the messages before stay readable."""
    real_write = McapRecorder.write_encoded
    written = []

    def disk_full_after_1000(self: McapRecorder, topic: str, log_time_ns: int,
                             data: bytes) -> None:
        if len(written) >= 1000:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        written.append(topic)
        real_write(self, topic, log_time_ns, data)

    monkeypatch.setattr(McapRecorder, "write_encoded", disk_full_after_1000)
    out = tmp_path / "full.mcap"
    with _served() as (link, _):
        recorder = PipedRecorder(link, out, epoch_ns=EPOCH_NS)
        with pytest.raises(OSError) as raised:
            _record(recorder, 6000)
        assert raised.value.errno == errno.ENOSPC
        recorder.close()
    assert read_summary(out).message_count == 1000


def test_a_run_that_dies_leaves_a_finished_log_with_all_it_sent(tmp_path: Path) -> None:
    """The run's process ends without closing (a crash): the server finishes the published
    log, summary included, with every message sent; an unpublished one is removed."""
    out = tmp_path / "crashed.mcap"
    with _served() as (link, _):
        recorder = PipedRecorder(link, out, epoch_ns=EPOCH_NS)
        _record(recorder, 3000)
        recorder._flush()  # what was sent before the crash (the buffer's last 64 KB at most)
    with out.open("rb") as file:
        summary = make_reader(file).get_summary()
    assert summary is not None and summary.statistics.message_count == 3000
    assert not read_summary(out).truncated

    unpublished = tmp_path / "early.mcap"
    with _served() as (link, _):
        PipedRecorder(link, unpublished)
    assert not unpublished.exists() and not partial_path(unpublished).exists()


def test_a_ctrl_c_during_a_request_is_raised_after_its_answer(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A Ctrl-C that lands while the run reads the server's answer (here after its first
    byte, as one did under load in `cosim run`'s set-up) is raised once the answer is in:
    closing then reads its own answer and the log is finished. Before, the interrupt cut the
    line, closing read its rest as its answer and failed: "the process writing the log has
    ended"."""
    out = tmp_path / "interrupted.mcap"
    real_read = os.read
    interrupted: list[int] = []
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with _served() as (link, _):
            recorder = PipedRecorder(link, out, epoch_ns=EPOCH_NS)

            def read_then_interrupt(descriptor: int, size: int) -> bytes:
                data = real_read(descriptor, size)
                if descriptor == link.answers_fd and not interrupted:
                    interrupted.append(descriptor)
                    os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C, mid-answer
                return data

            recorder.register("/a", {"title": "test.a", "type": "object"})
            monkeypatch.setattr(piped_recorder.os, "read", read_then_interrupt)
            with pytest.raises(KeyboardInterrupt):
                recorder.publish()
            monkeypatch.undo()
            recorder.write("/a", 0.0, {"i": 1})
            recorder.close()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert interrupted
    summary = read_summary(out)
    assert not summary.truncated and summary.message_count == 1
