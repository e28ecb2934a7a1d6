"""The user's interrupts (``SIGINT``: Ctrl-C, ``SIGTERM``: ``kill``) sent to one handler for a
while: the run's loop stops cleanly on either (:mod:`cosim.simulation.runner`), and the
command that watches a run passes either on to it (:mod:`cosim.cli.guard`)."""

from __future__ import annotations

import contextlib
import signal
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
