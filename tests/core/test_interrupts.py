"""An interrupt that lands where Python cannot raise it (a weakref callback) prints nothing
once a command's process has :func:`cosim.core.interrupts.drop_unraisable_interrupts`;
other unraisable errors are still printed."""

from __future__ import annotations

import subprocess
import sys

import pytest

PROGRAM = """
import gc, sys, weakref
from cosim.core.interrupts import drop_unraisable_interrupts
if sys.argv[1] == "dropped":
    drop_unraisable_interrupts()
class Thing:
    pass
def callback(reference):
    raise {error}
thing = Thing()
reference = weakref.ref(thing, callback)
del thing
gc.collect()
print("went on")
"""


def _run(error: str, mode: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", PROGRAM.format(error=error), mode],
                          capture_output=True, text=True, timeout=60, check=False)


@pytest.mark.parametrize("mode", ["dropped", "default"])
def test_an_interrupt_in_a_weakref_callback_prints_a_traceback_only_without_the_hook(
        mode: str) -> None:
    done = _run("KeyboardInterrupt", mode)
    assert done.returncode == 0 and done.stdout.strip() == "went on"
    if mode == "dropped":
        assert done.stderr == ""
    else:  # what the hook is for: Python prints the ignored interrupt with a traceback
        assert "Traceback" in done.stderr and "KeyboardInterrupt" in done.stderr


def test_other_unraisable_errors_are_still_printed() -> None:
    done = _run("ValueError('a real bug')", "dropped")
    assert "Traceback" in done.stderr and "a real bug" in done.stderr
