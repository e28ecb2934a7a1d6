"""Importing MuJoCo for physics only, whatever ``MUJOCO_GL`` says.

MuJoCo picks its OpenGL back-end from ``MUJOCO_GL`` when it is first imported, and an
unusable value (a typo, or ``egl`` on a machine without EGL) makes ``import mujoco`` fail.
The plant needs no OpenGL: :func:`import_mujoco` (and dm_control's PyMJCF, under
:func:`headless_gl`) imports it with ``MUJOCO_GL=disable`` and
puts the variable back as it was, so the user's choice still reaches ``cosim render``, which
renders in a child process with its own environment (:mod:`cosim.plots.render`).
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from types import ModuleType


@contextlib.contextmanager
def headless_gl() -> Iterator[None]:
    """``MUJOCO_GL=disable`` inside the block (for imports of mujoco and dm_control), the
    user's value (or none) again after it."""
    previous = os.environ.get("MUJOCO_GL")
    os.environ["MUJOCO_GL"] = "disable"
    try:
        yield
    finally:
        if previous is None:
            del os.environ["MUJOCO_GL"]
        else:
            os.environ["MUJOCO_GL"] = previous


def import_mujoco() -> ModuleType:
    """``mujoco``, imported without OpenGL if this process has not imported it yet."""
    if "mujoco" in sys.modules:
        return sys.modules["mujoco"]
    with headless_gl():
        import mujoco
    return mujoco
