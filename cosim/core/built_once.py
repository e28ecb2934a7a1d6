"""Builders run once per process: :func:`built_once`.

A run's set-up builds things from its configuration alone: CasADi graphs of its models, the
car's MJCF. Built anew for every run of a process (a test session, a script running many
runs), they cost more than the run they serve; built once and shared, they cost nothing
the second time. A builder decorated with :func:`built_once` is a pure function of its
arguments (the same arguments give an equal result), and its result is immutable or
copied by its callers before they change it.

Arguments are compared exactly: by equality and by their ``repr``, so that settings that
compare equal but are not the same numbers (``0.0`` and ``-0.0``) are built apart, and a
run's result never depends on which equal-looking configuration ran before it. A few
results are kept (least recently used first out): a process that goes through many
configurations rebuilds, as it did before.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import ParamSpec, TypeVar

Params = ParamSpec("Params")
Result = TypeVar("Result")

KEPT = 8
"""Results kept per builder."""


def built_once(build: Callable[Params, Result]) -> Callable[Params, Result]:
    """``build`` with its results kept for equal arguments (module docstring). Arguments
    must be hashable; keyword arguments are part of the key as given."""

    @functools.lru_cache(maxsize=KEPT)
    def cached(exact: str, *args: object, **kwargs: object) -> Result:
        del exact  # part of the key only
        return build(*args, **kwargs)  # type: ignore[arg-type]

    @functools.wraps(build)
    def once(*args: Params.args, **kwargs: Params.kwargs) -> Result:
        return cached(repr((args, sorted(kwargs.items()))), *args, **kwargs)

    return once
