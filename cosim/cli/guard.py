"""A run in a child process watched by its parent, so that foreign native code cannot take
the user's answer with it.

A tracker FMU's shared library or a plug-in runs inside the simulation's process. When it
ends that process (a segmentation fault, ``abort()``, ``os._exit``, a C ``exit()``), no
Python handler runs: the command used to end with the library's exit status and nothing
said, and an interrupt during set-up could be swallowed by native code before the run's own
signal handler was in place. :func:`guarded` therefore forks (``fork(2)``, after the
configuration is read and the log's name is claimed) and runs the rest of the command in
the child. The child reports through a pipe, one line each:

* ``log <path>`` once the log's name is claimed, ``tracker <name>`` once the configuration
  is read;
* ``ready`` once the run's loop holds its signal handler (``SIGINT``/``SIGTERM`` stop it
  cleanly, the log finished up to there);
* ``t <seconds>`` as the simulated time advances;
* ``exit <code>`` just before it ends on its own.

The parent also writes the run's log: the child's recorder sends it the encoded messages
down a second pipe (:mod:`cosim.log.piped_recorder`), so that the MCAP writer and its
compression run on the other core, and a child that dies leaves its log finished with every
message it had sent. Otherwise the parent waits. An interrupt (``SIGINT``, ``SIGTERM``) is
passed on to the child once it is ready; a second one before that ends the child at once (a
set-up that hangs). A child
that ends without its ``exit`` line died: the parent returns a :class:`Death` naming how
(exit status or signal) and the last simulated time reached, and the caller says which
component is the likely cause and where the log up to then is
(:func:`cosim.log.reader.read_summary` reads a log up to its last complete chunk).

The cost is one ``fork`` of an interpreter that has imported the simulation (about a
millisecond of page-table copy on Linux), a pipe write every progress step, and the
parent's import of foxglove-sdk while the child imports the simulation. Where
``fork`` does not exist the body runs in this process, unguarded.
"""

from __future__ import annotations

import contextlib
import os
import selectors
import shutil
import signal
import sys
import traceback
from collections.abc import Callable, Iterator
from dataclasses import astuple, dataclass, field
from typing import Any

from cosim.core.compiled_cache import private_folder
from cosim.core.interrupts import INTERRUPTS, interrupts_to
from cosim.log.piped_recorder import LogLink, LogServer, log_pipes

FORCE_AFTER_SIGNALS = 2
"""Signals received before the child is ready that end it at once (``SIGKILL``)."""


@dataclass(frozen=True)
class Death:
    """How a guarded child ended without finishing."""

    how: str
    """``exit status 7``, ``signal SIGSEGV`` ..."""
    last_t_s: float | None
    """The last simulated time the child reported (None: before the run's loop)."""
    log_path: str | None
    """The log the child claimed (None: it had not got that far)."""
    tracker: str | None
    """The run's tracker (None: the configuration was not read yet)."""
    interrupted: bool
    """The user's interrupt ended it: a second one during set-up (the parent ended the
    child at once) or a signal the child took before its handlers were in place."""


class Reporter:
    """The child's side of the pipe (a no-op in an unguarded run)."""

    def __init__(self, descriptor: int | None, log_link: LogLink | None = None) -> None:
        self._descriptor = descriptor
        self.log_link = log_link
        """The pipes to the parent that writes the run's log
        (:class:`cosim.log.piped_recorder.PipedRecorder`; None: the child writes it)."""

    def _send(self, line: str) -> None:
        if self._descriptor is not None:
            with contextlib.suppress(OSError):
                os.write(self._descriptor, f"{line}\n".encode(errors="surrogateescape"))

    def log(self, path: object) -> None:
        """The run's log is ``path``."""
        self._send(f"log {path}")

    def tracker(self, name: str) -> None:
        """The run's tracker is ``name``."""
        self._send(f"tracker {name}")

    def ready(self) -> None:
        """The run's loop holds its signal handler."""
        self._send("ready")

    def reached(self, t_s: float) -> None:
        """The simulated time ``t_s`` [s] is reached."""
        self._send(f"t {t_s:.6g}")

    def exiting(self, code: int) -> None:
        self._send(f"exit {code}")


def guarded(body: Callable[[Reporter], int]) -> int | Death:
    """``body(reporter)`` in a forked child: its exit code, or the :class:`Death` of a child
    that ended without finishing. Without ``os.fork``, ``body`` runs here."""
    if not hasattr(os, "fork"):
        return body(Reporter(None))
    for stream in (sys.stdout, sys.stderr):  # nothing buffered is written twice
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
    read_end, write_end = os.pipe()
    link, server_ends = log_pipes()
    parent = os.getpid()
    # The parent's handlers are in place before the fork: no interrupt falls between.
    with _forwarding_signals() as state:
        child = os.fork()
        if child == 0:  # pragma: no cover - the child's coverage is not collected
            for descriptor in (read_end, *astuple(server_ends)):
                os.close(descriptor)
            _die_with(parent)
            _child(body, Reporter(write_end, link))
        state.child = child
        for descriptor in (write_end, *astuple(link)):
            os.close(descriptor)
        server = LogServer(server_ends)
        try:
            _follow(read_end, server_ends.frames_fd, server, state)
        finally:
            server.finish()  # a child that died: its log finished with what arrived
            for descriptor in astuple(server_ends):
                os.close(descriptor)
    os.close(read_end)
    _, status = _wait(child)
    # The child ends with os._exit (or a signal): its exit handlers, which remove the
    # libraries it built for itself where the cache could not take them, never ran.
    shutil.rmtree(private_folder(child), ignore_errors=True)
    if state.code is not None:
        return state.code
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        how = f"signal {signal.Signals(number).name}" if number in _SIGNALS else \
            f"signal {number}"
    else:
        how = f"exit status {os.WEXITSTATUS(status)}"
    interrupted = state.forced or (state.signalled and os.WIFSIGNALED(status) and
                                   os.WTERMSIG(status) in _INTERRUPTS)
    return Death(how=how, last_t_s=state.last_t_s, log_path=state.log_path,
                 tracker=state.tracker, interrupted=interrupted)


_SIGNALS = {s.value for s in signal.Signals}
_INTERRUPTS = (signal.SIGINT, signal.SIGTERM, signal.SIGKILL)


PR_SET_PDEATHSIG = 1
"""``prctl(2)``: the signal a process gets when its parent ends."""


def _die_with(parent: int) -> None:  # pragma: no cover - runs in the child
    """End this child when its parent ends (``kill -9`` of the command ends the run, as
    before the guard); Linux only, elsewhere the child runs on to its end."""
    with contextlib.suppress(OSError, AttributeError):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:  # the parent ended before prctl
        os._exit(1)


def _child(body: Callable[[Reporter], int], reporter: Reporter) -> None:  # pragma: no cover
    """Run ``body`` and end the child with its code (never returns)."""
    code = 1
    # Ctrl-C and SIGTERM during set-up interrupt it (the run's loop takes both over).
    for signum in INTERRUPTS:
        signal.signal(signum, signal.default_int_handler)
    try:
        code = body(reporter)
    except SystemExit as done:
        code = done.code if isinstance(done.code, int) else 1
    except BaseException:  # a bug: shown as Python would show it at exit
        traceback.print_exc()
    finally:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):
                stream.flush()
        reporter.exiting(code)
        os._exit(code)


@dataclass
class _State:
    child: int = 0
    """The child's process id (0 until it is forked)."""
    ready: bool = False
    pending: list[int] = field(default_factory=list)
    """Interrupts received before the child was ready, passed on when it is."""
    code: int | None = None
    last_t_s: float | None = None
    log_path: str | None = None
    tracker: str | None = None
    forced: bool = False
    signalled: bool = False


@contextlib.contextmanager
def _forwarding_signals() -> Iterator[_State]:
    """SIGINT and SIGTERM of the parent go to the child once it is ready."""
    state = _State()

    def forward(signum: int, frame: Any) -> None:
        del frame
        state.signalled = True
        if state.ready:
            with contextlib.suppress(ProcessLookupError):
                os.kill(state.child, signum)
            return
        state.pending.append(signum)
        if len(state.pending) >= FORCE_AFTER_SIGNALS and state.child:
            state.forced = True
            with contextlib.suppress(ProcessLookupError):
                os.kill(state.child, signal.SIGKILL)

    with interrupts_to(forward):
        yield state


def _follow(read_end: int, frames: int, server: LogServer, state: _State) -> None:
    """Read the child's lines (``read_end``) and its log's frames (``frames``, fed to
    ``server``) until it closes both pipes."""
    buffer = b""
    with selectors.DefaultSelector() as selector:
        selector.register(read_end, selectors.EVENT_READ)
        selector.register(frames, selectors.EVENT_READ)
        while selector.get_map():
            for key, _ in selector.select(timeout=0.5):
                data = os.read(key.fd, LOG_READ_BYTES if key.fd == frames else 4096)
                if not data:
                    selector.unregister(key.fd)
                elif key.fd == frames:
                    server.feed(data)
                else:
                    buffer += data
                    *lines, buffer = buffer.split(b"\n")
                    for line in lines:
                        _take(line.decode(errors="surrogateescape"), state)


LOG_READ_BYTES = 256 * 1024
"""The most of the log's frames read at once."""


def _take(line: str, state: _State) -> None:
    word, _, value = line.partition(" ")
    if word == "ready":
        state.ready = True
        for signum in state.pending:
            with contextlib.suppress(ProcessLookupError):
                os.kill(state.child, signum)
        state.pending = []
    elif word == "t":
        with contextlib.suppress(ValueError):
            state.last_t_s = float(value)
    elif word == "log":
        state.log_path = value
    elif word == "tracker":
        state.tracker = value
    elif word == "exit":
        with contextlib.suppress(ValueError):
            state.code = int(value)


def _wait(child: int) -> tuple[int, int]:
    while True:
        try:
            return os.waitpid(child, 0)
        except InterruptedError:  # pragma: no cover - PEP 475 retries for us
            continue
