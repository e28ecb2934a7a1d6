"""The filter's models evaluated as C: every process and measurement function of a filter
compiled into one library (:mod:`cosim.core.compiled_function`) and called in place of
CasADi's virtual machine. Their numbers (the belief, the noise) are inputs, so one library
serves every belief and is built once per machine."""

from __future__ import annotations

import warnings

from cosim.core.compiled_function import CompiledCacheWarning, compiler, load_library
from cosim.core.dense_function import DenseFunction

FILTER_FLAGS = ("-O1",)
"""The filters' models are compiled at ``-O1``: gcc takes 7 s on their 1.5 MB of C against
12 s at ``-O2``, and the filter runs as fast (a lane change's filter calls replayed)."""


def use_compiled(kind: str, functions: tuple[DenseFunction, ...]) -> None:
    """Evaluate ``functions`` as C: one library for all of them, compiled on first use
    (with a one-line note) and cached; with a one-line warning, CasADi's virtual machine
    when no C compiler works. Their numbers are inputs, so the library serves every
    belief: it is built once per machine."""
    if not functions:
        return
    fallback = (f"the {kind}'s models run in CasADi's virtual machine, about 2x slower "
                "(estimator.compiled=false says so quietly)")
    library = load_library(f"cosim_{kind.lower()}",
                           [function.function for function in functions],
                           note=f"compiling the {kind}'s models to C (5-10 s)",
                           fallback=fallback, flags=FILTER_FLAGS)
    if library is None:
        if compiler() is None:  # a failed build or load has said why
            warnings.warn(f"no working C compiler (gcc, or $CC): {fallback}",
                          CompiledCacheWarning, stacklevel=3)
        return
    for function in functions:
        function.use_compiled(library)
