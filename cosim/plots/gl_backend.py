"""The OpenGL back-end of the video renderer: which one, whether it can work here, and the
environment of the process that renders with it.

MuJoCo picks how it gets an OpenGL context from ``MUJOCO_GL`` once, when ``mujoco`` is first
imported; the plant imports it with ``MUJOCO_GL=disable``. So rendering runs in a child
process whose environment (:func:`gl_environment`) names the back-end; a missing one is a
:class:`~cosim.core.exceptions.GlBackendError` naming the package to install.
"""

from __future__ import annotations

import ctypes.util
import os
from collections.abc import Callable
from typing import Any

from cosim.core.exceptions import GlBackendError

GL_BACKENDS: tuple[str, ...] = ("osmesa", "egl", "glfw")
"""The values of ``--gl`` (and of ``MUJOCO_GL`` that rendering honours)."""

DEFAULT_GL = "osmesa"
"""Back-end when ``MUJOCO_GL`` is unset or ``disable``: software, works without a GPU."""

GL_MISSING: dict[str, str] = {
    "osmesa": "the OSMesa library (libOSMesa) is not installed",
    "egl": "the EGL library (libEGL) is not installed",
    "glfw": "GLFW needs a display (DISPLAY and WAYLAND_DISPLAY are unset)",
}
"""What :func:`check_gl_backend` found missing, per back-end."""

GL_REMEDIES: dict[str, str] = {
    "osmesa": "install OSMesa (Debian/Ubuntu: apt-get install libosmesa6; Fedora: dnf install "
              "mesa-libOSMesa) or render on a GPU with --gl egl",
    "egl": "install EGL with the GPU's driver (Debian/Ubuntu: apt-get install libegl1) or "
           "render in software with --gl osmesa",
    "glfw": "render headless with --gl osmesa (software) or --gl egl (GPU)",
}
"""What the user can do about a back-end that is missing or does not start."""


def default_gl(environ: dict[str, str] | os._Environ[str] = os.environ) -> str:
    """``MUJOCO_GL`` if it names a back-end of :data:`GL_BACKENDS`, else :data:`DEFAULT_GL`
    (``disable``, the simulation's setting, and unset both mean "choose for me")."""
    value = environ.get("MUJOCO_GL", "").strip().lower()
    return value if value in GL_BACKENDS else DEFAULT_GL


def check_gl_backend(gl: str, environ: dict[str, str] | os._Environ[str] = os.environ,
                     find_library: Callable[[str], str | None] = ctypes.util.find_library
                     ) -> None:
    """Raise :class:`GlBackendError` with an install hint if ``gl`` cannot work here.

    A cheap check before MuJoCo tries (and fails less legibly): the shared library of
    ``osmesa``/``egl`` must be found by the dynamic loader, ``glfw`` needs a display.
    """
    if gl not in GL_BACKENDS:
        raise GlBackendError(f"MUJOCO_GL={gl}: expected one of {', '.join(GL_BACKENDS)}")
    if gl == "osmesa":
        missing = find_library("OSMesa") is None
    elif gl == "egl":
        missing = find_library("EGL") is None
    else:
        missing = not (environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"))
    if missing:
        raise GlBackendError(f"--gl {gl}: {GL_MISSING[gl]}: {GL_REMEDIES[gl]}")


def gl_environment(gl: str, environ: dict[str, str] | os._Environ[str] = os.environ
                   ) -> dict[str, str]:
    """The environment of the rendering process: ``environ`` with ``MUJOCO_GL`` and
    ``PYOPENGL_PLATFORM`` set for ``gl`` (PyOpenGL must agree with MuJoCo's context;
    GLFW uses PyOpenGL's default platform, so the variable is removed for it)."""
    env = dict(environ)
    env["MUJOCO_GL"] = gl
    if gl == "glfw":
        env.pop("PYOPENGL_PLATFORM", None)
    else:
        env["PYOPENGL_PLATFORM"] = gl
    return env


def import_mujoco(gl: str) -> Any:
    """``mujoco``, checking that this process imported it for ``gl``."""
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    if requested != gl:
        raise GlBackendError(f"MUJOCO_GL={requested or '(unset)'} in this process, but "
                             f"rendering with {gl} needs MUJOCO_GL={gl} before mujoco is "
                             "imported (use cosim.plots.render.render_log)")
    try:
        import mujoco
    except Exception as error:  # noqa: BLE001 - a broken GL stack fails in many ways
        raise GlBackendError(f"MUJOCO_GL={gl}: importing mujoco failed ({error}): "
                             f"{GL_REMEDIES[gl]}") from None
    return mujoco
