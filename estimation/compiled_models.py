"""The filter's models evaluated as C: every process and measurement function of a filter
compiled into one library (:mod:`cosim.core.compiled_function`) and called in place of
CasADi's virtual machine. Their numbers (the belief, the noise) are inputs, so one library
serves every belief and is built once per machine."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

from cosim.core.built_on_disk import PROJECT_PACKAGES
from cosim.core.compiled_function import (
    CompiledCacheWarning,
    compiler,
    load_library,
    recorded_library,
)
from cosim.core.dense_function import DenseFunction

FILTER_FLAGS = ("-O1",)
"""The filters' models are compiled at ``-O1``: gcc takes about half the time it takes at
``-O2`` on their long straight-line C (the EKF's 2.0 MB: 13 s against 24 s, 2026-12-07),
and the filter runs as fast (a lane change's filter calls replayed)."""


def use_compiled(kind: str, functions: tuple[DenseFunction, ...],
                 recipe: str | None = None) -> None:
    """Evaluate ``functions`` as C: one library for all of them, compiled on first use
    (with a one-line note) and cached; with a one-line warning, CasADi's virtual machine
    when no C compiler works. Their numbers are inputs, so the library serves every
    belief: it is built once per machine. ``recipe``: what the functions are built from
    (:func:`cosim.core.compiled_function.load_library`), so a new process finds the
    library without serialising them."""
    if not functions:
        return
    fallback = (f"the {kind}'s models run in CasADi's virtual machine, about 2x slower "
                "(estimator.compiled=false says so quietly)")
    library = load_library(f"cosim_{kind.lower()}",
                           [function.function for function in functions],
                           note=f"compiling the {kind}'s models to C (8-15 s)",
                           fallback=fallback, flags=FILTER_FLAGS, recipe=recipe)
    if library is None:
        if compiler() is None:  # a failed build or load has said why
            warnings.warn(f"no working C compiler (gcc, or $CC): {fallback}",
                          CompiledCacheWarning, stacklevel=3)
        return
    for function in functions:
        function.use_compiled(library)


def recorded(kind: str, recipe: str | None) -> Path | None:
    """The library :func:`use_compiled` would load for ``recipe``, when an earlier process
    kept it (:func:`cosim.core.compiled_function.recorded_library`): a filter may take
    functions from it (``casadi.external``) instead of building their graphs; None when
    there is none yet, or no recipe."""
    if recipe is None:
        return None
    return recorded_library(f"cosim_{kind.lower()}", recipe, flags=FILTER_FLAGS)


def recipe(cls: type, *arguments: Any) -> str | None:
    """What a filter of class ``cls`` builds its models from (``arguments``: its
    configuration and belief, more than the models depend on: equal recipes give equal
    functions with the same code), for :func:`use_compiled`; None for a class outside the
    project, whose code the cache's stamp does not cover (:mod:`cosim.core.built_on_disk`)."""
    if cls.__module__.split(".")[0] not in PROJECT_PACKAGES:
        return None
    return "\n".join((f"{cls.__module__}.{cls.__qualname__}", *map(repr, arguments)))
