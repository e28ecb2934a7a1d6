"""How a run is stopped and timed: the stop request that Ctrl-C and SIGTERM set while the
loop runs, and the wall clock that starts after the run's set-up.

A stop is a flag the loop checks once per physics step (:class:`StopRequest`), not Python's
``KeyboardInterrupt``: CasADi polls for signals inside IPOPT and would turn the exception
into a failed solve, which the tracker rightly survives. The clock (:class:`WallClock`)
starts when the loop does, so that a first run's compile is its ``setup_time_s`` and its
``realtime_factor`` is the simulation's.
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

from cosim.core.interrupts import interrupts_to


class StopRequest:
    """Set by SIGINT/SIGTERM while a run goes; the loop checks it once per physics step."""

    def __init__(self) -> None:
        self.signal_name = ""

    def __call__(self, signum: int, frame: object) -> None:
        del frame
        self.signal_name = signal.Signals(signum).name


@contextlib.contextmanager
def stop_on_signals() -> Iterator[StopRequest]:
    """A :class:`StopRequest` that SIGINT and SIGTERM set while the block runs (in the main
    thread; elsewhere nothing sets it)."""
    request = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request  # signal handlers can only be set from the main thread
        return
    with interrupts_to(request):
        yield request


@dataclass(frozen=True)
class WallClock:
    """When the run was called and when its loop started (``time.perf_counter``): the run's
    clock starts after its set-up, where models are built and code compiled, so that a first
    run's ``realtime_factor`` is the simulation's, not the compiler's."""

    called_s: float
    loop_start_s: float

    def times(self) -> tuple[float, float]:
        """``(setup_time_s, wall_time_s)``: set-up, and the loop up to now."""
        return self.loop_start_s - self.called_s, time.perf_counter() - self.loop_start_s
