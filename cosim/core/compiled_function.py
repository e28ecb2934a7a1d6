"""A CasADi function as C, compiled once with the system's C compiler and called in place.

CasADi generates C for any :class:`~casadi.Function` (``CodeGenerator``); compiled with
``gcc -O2`` into a shared library it runs without CasADi's virtual machine, and called
through :mod:`ctypes` on numpy buffers that stay bound to it, a call costs a few
microseconds instead of the tens that converting numpy arrays to CasADi matrices takes on
every call of ``function(...)``. Inputs may be any float64 C-contiguous arrays whose memory
outlives the binding, MuJoCo's ``MjData`` arrays included (their memory is fixed for the
life of the ``MjData``), so a physics step passes MuJoCo's state with no copy at all.

The library is cached under ``$XDG_CACHE_HOME/cosim`` (``~/.cache/cosim``), named by a
hash of the generated source, so a given function is compiled once per machine (about a
second); :func:`compile_function` returns None when no C compiler works, and the caller
keeps its plain implementation.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

import casadi as ca
import numpy as np

COMPILER_FLAGS = ("-O2",)
"""Optimisation flags (``-shared -fPIC`` are always added)."""


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "cosim"


class CompiledFunction:
    """One compiled CasADi function bound to its input and output buffers.

    ``inputs`` and ``outputs`` are float64, C-contiguous numpy arrays holding each
    argument densely (sizes checked against the function); :meth:`__call__` evaluates the
    function from the inputs' current contents into the outputs.
    """

    def __init__(self, library: ctypes.CDLL, function: ca.Function,
                 inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray]) -> None:
        for kind, arrays, count, size in (
            ("input", inputs, function.n_in(), function.nnz_in),
            ("output", outputs, function.n_out(), function.nnz_out),
        ):
            if len(arrays) != count:
                raise ValueError(f"{function.name()}: {len(arrays)} {kind}s, expected {count}")
            for i, array in enumerate(arrays):
                if (array.dtype != np.float64 or not array.flags.c_contiguous
                        or array.size != size(i)):
                    raise ValueError(f"{function.name()}: {kind} {i} must be a C-contiguous "
                                     f"float64 array of {size(i)} numbers")
        self._keep = (tuple(inputs), tuple(outputs))  # the buffers outlive the pointers
        self._entry = getattr(library, function.name())
        self._entry.restype = ctypes.c_int
        self._library = library
        pointer = ctypes.c_void_p
        self._arg = (pointer * max(function.sz_arg(), 1))(*[a.ctypes.data for a in inputs])
        self._res = (pointer * max(function.sz_res(), 1))(*[a.ctypes.data for a in outputs])
        self._iw = (ctypes.c_longlong * max(function.sz_iw(), 1))()
        self._w = (ctypes.c_double * max(function.sz_w(), 1))()
        self._name = function.name()

    def __call__(self) -> None:
        if self._entry(self._arg, self._res, self._iw, self._w, 0):
            raise RuntimeError(f"{self._name}: the compiled function reported an error")


def compiled_library(name: str, functions: Sequence[ca.Function],
                     flags: Sequence[str] = COMPILER_FLAGS) -> Path | None:
    """The shared library holding ``functions`` (each under its own name), compiled with
    ``flags`` or found in the cache; None when no C compiler is available or compiling
    fails. ``name`` names the file (a C identifier)."""
    compiler = shutil.which(os.environ.get("CC", "gcc"))
    if compiler is None:
        return None
    flags = (*flags, "-shared", "-fPIC")
    with tempfile.TemporaryDirectory() as tmp:
        generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
        for function in functions:
            generator.add(function)
        generator.generate(f"{tmp}/")
        source = Path(tmp, f"{name}.c").read_bytes()
        digest = hashlib.sha256(source + " ".join(flags).encode()).hexdigest()[:16]
        library = _cache_dir() / f"{name}-{digest}.so"
        if not library.is_file():
            try:
                library.parent.mkdir(parents=True, exist_ok=True)
                partial = Path(tmp, library.name)
                subprocess.run([compiler, *flags, "-o", str(partial),
                                str(Path(tmp, f"{name}.c")), "-lm"],
                               check=True, capture_output=True)
                # Atomic: a concurrent run (a sweep's workers) never loads half a file.
                shutil.copyfile(partial, f"{library}.{os.getpid()}")
                os.replace(f"{library}.{os.getpid()}", library)
            except (OSError, subprocess.CalledProcessError):
                return None
    return library


def compile_function(function: ca.Function) -> ctypes.CDLL | None:
    """The shared library of ``function`` (compiled or from the cache), or None when no C
    compiler is available or compiling fails."""
    library = compiled_library(function.name(), [function])
    if library is None:
        return None
    try:
        return ctypes.CDLL(str(library))
    except OSError:
        return None
