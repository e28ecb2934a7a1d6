"""The user's interrupts (``SIGINT``: Ctrl-C, ``SIGTERM``: ``kill``) sent to one handler for a
while: the run's loop stops cleanly on either (:mod:`cosim.simulation.runner`), and the
command that watches a run passes either on to it (:mod:`cosim.cli.guard`)."""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

INTERRUPTS = (signal.SIGINT, signal.SIGTERM)
"""The signals a user stops a command with."""


@contextlib.contextmanager
def interrupts_to(handler: Callable[[int, Any], None]) -> Iterator[None]:
    """``handler(signum, frame)`` takes :data:`INTERRUPTS` while the block runs; the handlers
    before are put back after it, however it ends. Only the main thread may set handlers:
    the caller checks that."""
    previous = {s: signal.signal(s, handler) for s in INTERRUPTS}
    try:
        yield
    finally:
        for signum, before in previous.items():
            signal.signal(signum, before)


@contextlib.contextmanager
def interrupts_held() -> Iterator[None]:
    """The block runs whole: an interrupt (:data:`INTERRUPTS`) that arrives during it is held,
    and delivered to the handler before the block as soon as the block ends, however it ends.

    For an exchange that must not be cut in half: a request to the process writing the log
    and the read of its answer (:class:`cosim.log.piped_recorder.PipedRecorder`). A Ctrl-C
    that raised ``KeyboardInterrupt`` between two bytes of the answer left the rest of the
    line in the pipe, and the next request read it as its own answer. Setting the handlers
    costs a few microseconds: for rare exchanges, not for every message. In a thread other
    than the main one (where handlers cannot be set) the block simply runs."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []

    def hold(signum: int, frame: Any) -> None:
        del frame
        held.append(signum)

    try:
        with interrupts_to(hold):
            yield
    finally:
        for signum in held:  # the handlers before are back: each takes its signal now
            signal.raise_signal(signum)


def drop_unraisable_interrupts() -> None:
    """Make an interrupt that lands where Python cannot raise it go unprinted.

    A handler that raises ``KeyboardInterrupt`` (a sweep worker's ``SIGTERM``) raises it in
    whatever Python code runs when the signal arrives. In a weakref callback or a
    finaliser (the import system's module locks have one) the exception cannot propagate:
    Python prints it as "Exception ignored in ..." with a traceback
    (``sys.unraisablehook``), on a command that was asked to stop and otherwise stops
    with one line. This process's hook then drops such interrupts and passes every other
    unraisable exception to the hook it had. For a command's own process only (it
    replaces a process-wide hook): the console script and the sweep's workers call it."""
    previous = sys.unraisablehook

    def hook(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            return
        previous(unraisable)

    sys.unraisablehook = hook
