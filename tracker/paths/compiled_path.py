"""A reference path's projection and horizon as C calls (``reference_path.c``).

:meth:`tracker.paths.reference_path.ReferencePath.project` finds the nearest point of a
table (a few hundred to a few thousand points) with numpy, then takes three Newton steps
on the spline in plain floats: some 25 us a call, and a run calls it at every log instant
(the metrics' cross-track error) and every control step (the MPC's reference). The C does
the same operations in the same order (Python's remainder, ``min``/``max`` and numpy's
``argmin`` kept where C's differ), so it gives the same numbers to the bit in a few
microseconds. Most of the MPC's spline reference over its horizon
(:func:`tracker.mpc.horizon_reference.horizon_reference`: the projection, the stages' arc
lengths and the spline's values there, some 25 numpy operations on arrays of 25) is one
call too, also to the bit; the headings and curvature stay numpy's (its SIMD ``arctan2``
and power differ from the C library's in the last bit for some arguments).
``tests/tracker/paths/test_compiled_path.py`` holds both to the Python.

The library is compiled once per machine (a fraction of a second; cached as every library
is, :mod:`cosim.core.compiled_function`) and loaded once per process. Without a working C
compiler the Python projection serves: the other libraries of a run say so already.
"""

from __future__ import annotations

import ctypes
import functools
import warnings
from pathlib import Path

import numpy as np

from cosim.core.compiled_function import CompileFailedWarning, compiled_library

SOURCE = Path(__file__).with_name("reference_path.c")

FALLBACK = "paths are projected in Python, about 25 us a call instead of a few"
"""What a run does without the library (said in its one warning line)."""


@functools.lru_cache(maxsize=1)
def path_library() -> ctypes.CDLL | None:
    """``reference_path.c`` compiled (or from the cache) and loaded, once per process; None
    without a working compiler or when the library does not load (with a warning)."""
    built = compiled_library("cosim_reference_path", [], key="reference path",
                             extra_sources=(SOURCE,), fallback=FALLBACK)
    if built is None:
        return None
    try:
        library = ctypes.CDLL(str(built))
        entry, horizon = library.cosim_path_project, library.cosim_path_horizon
    except (OSError, AttributeError) as error:
        warnings.warn(f"cannot load the compiled path projection {str(built)!r} ({error}): "
                      f"{FALLBACK}", CompileFailedWarning, stacklevel=2)
        return None
    pointer, double, long = ctypes.c_void_p, ctypes.c_double, ctypes.c_long
    out = ctypes.POINTER(double)
    entry.argtypes = (pointer, long, pointer, pointer, long, pointer, double, double,
                      ctypes.c_int, double, double, out)
    entry.restype = ctypes.c_int
    horizon.argtypes = (pointer, long, pointer, pointer, long, pointer, double, double,
                        pointer, long, double, out, pointer)
    horizon.restype = ctypes.c_int
    return library


_Projection = ctypes.c_double * 4
"""The C's projection: s_m, lateral_error_m, path_yaw_rad, curvature_1pm."""


class CompiledPath:
    """One path's C bound to its arrays: ``path(x_m, y_m, near_s_m, window_m)`` gives
    ``(s_m, lateral_error_m, path_yaw_rad, curvature_1pm)`` as
    :meth:`~tracker.paths.reference_path.ReferencePath.project` computes them;
    :meth:`horizon` the spline reference of a horizon."""

    def __init__(self, library: ctypes.CDLL, table_s: np.ndarray, table_x: np.ndarray,
                 table_y: np.ndarray, knots: np.ndarray, pieces: np.ndarray,
                 length_m: float, table_step_m: float, closed: bool) -> None:
        self._table = np.ascontiguousarray(np.vstack((table_s, table_x, table_y)),
                                           dtype=float)
        self._knots = np.ascontiguousarray(knots, dtype=float)
        self._pieces = np.ascontiguousarray(pieces, dtype=float)
        if self._pieces.ndim != 2 or self._pieces.shape[1] != 8 \
                or self._knots.size != self._pieces.shape[0] + 1:
            raise ValueError("pieces must be (n, 8) with n + 1 knots")
        if not self._table.shape[1]:
            raise ValueError("an empty path table")
        self._geometry = np.array([length_m, table_step_m, 1.0 if closed else 0.0])
        self._entry = library.cosim_path_project
        self._horizon = library.cosim_path_horizon
        self._library = library  # kept alive while its entry is used
        self._fixed = (self._table.ctypes.data, self._table.shape[1], self._knots.ctypes.data,
                       self._pieces.ctypes.data, self._pieces.shape[0],
                       self._geometry.ctypes.data)

    def __call__(self, x_m: float, y_m: float, near_s_m: float | None,
                 window_m: float) -> tuple[float, float, float, float]:
        windowed = near_s_m is not None
        out = _Projection()  # a call's own (ctypes lets threads call the C at once)
        self._entry(*self._fixed, x_m, y_m, windowed, near_s_m if windowed else 0.0, window_m,
                    out)  # (its status says only whether the table is empty: it is not)
        s_m, lateral_m, yaw_rad, curvature = out
        return s_m, lateral_m, yaw_rad, curvature

    def horizon(self, x_m: float, y_m: float, speeds_mps: np.ndarray,
                dt_s: float) -> tuple[tuple[float, float, float, float], np.ndarray]:
        """For a car at ``(x_m, y_m)`` and the ``N + 1`` speeds ``speeds_mps`` of a
        horizon: its projection onto the whole path (as :meth:`__call__` without a
        window) and the spline at the ``N`` stages' arc lengths
        (:func:`tracker.mpc.horizon_reference.horizon_reference`), rows ``s_m, x, y,
        dx/ds, dy/ds, d2x/ds2, d2y/ds2`` of a new array."""
        speeds = np.ascontiguousarray(speeds_mps, dtype=float)
        if speeds.ndim != 1 or speeds.size < 2:
            raise ValueError(f"expected N + 1 >= 2 speeds, got shape {speeds.shape}")
        stages = np.empty((7, speeds.size - 1))
        out = _Projection()
        self._horizon(*self._fixed, x_m, y_m, speeds.ctypes.data, stages.shape[1], dt_s, out,
                      stages.ctypes.data)
        s_m, lateral_m, yaw_rad, curvature = out
        return (s_m, lateral_m, yaw_rad, curvature), stages
