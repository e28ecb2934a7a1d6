"""Libraries are built for the processor of the machine (``-march=native``) with the numbers
of a plain build, keyed by that processor, and built plainly by a compiler without the flag."""

from __future__ import annotations

import os
import stat
import warnings
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import cosim.core.compiled_function as compiled
from cosim.core.compiled_function import compiled_library
from tests.core.compiled_probe import evaluated_at


@pytest.fixture()
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return tmp_path / "cache" / "cosim"


def _rk4_function() -> ca.Function:
    """Ten RK4 steps of a damped pendulum with a Jacobian: long chains of products and sums
    (where a fused multiply-add would round differently), sines and exponentials."""
    x = ca.SX.sym("x", 2)
    p = ca.SX.sym("p", 3)

    def f(s: ca.SX) -> ca.SX:
        return ca.vertcat(s[1], -p[0] * ca.sin(s[0]) - p[1] * s[1] * ca.exp(-p[2] * s[0] ** 2))

    s, h = x, 0.01
    for _ in range(10):
        k1 = f(s)
        k2 = f(s + h / 2 * k1)
        k3 = f(s + h / 2 * k2)
        k4 = f(s + h * k3)
        s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("native_probe", [x, p], [s, ca.densify(ca.jacobian(s, x))])




def _compiler_refusing_native(tmp_path: Path) -> str:
    """A ``CC`` that fails on ``-march=native`` and is gcc otherwise."""
    script = tmp_path / "cc-without-native"
    script.write_text('#!/bin/sh\nfor a in "$@"; do [ "$a" = -march=native ] && '
                      '{ echo "cc: unknown option -march=native" >&2; exit 1; }; done\n'
                      'exec gcc "$@"\n')
    script.chmod(script.stat().st_mode | stat.S_IXUSR)
    return str(script)


def test_a_native_build_gives_the_numbers_of_a_plain_one(
        cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    function = _rk4_function()
    points = np.random.default_rng(7).uniform([-3, -5, 1, 0.1, 0.1], [3, 5, 20, 2, 3],
                                              size=(200, 5))
    native = compiled_library("native_probe", [function], key="probe native")
    assert native is not None
    compiled.native_flags.cache_clear()
    monkeypatch.setenv("CC", _compiler_refusing_native(tmp_path))
    try:
        plain = compiled_library("native_probe", [function], key="probe plain")
    finally:
        compiled.native_flags.cache_clear()
    assert plain is not None and plain != native
    assert np.array_equal(evaluated_at(native, function, points),
                          evaluated_at(plain, function, points))


def test_a_compiler_without_the_flag_builds_plainly_and_says_nothing(
        cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CC", _compiler_refusing_native(tmp_path))
    compiled.native_flags.cache_clear()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a plain build is no failure
            built = compiled_library("native_probe", [_rk4_function()], key="probe refused")
        assert compiled.native_flags((os.environ["CC"],)) == ()
    finally:
        compiled.native_flags.cache_clear()
    assert built is not None and built.is_file()
    assert compiled.native_flags(("gcc",)) == compiled.NATIVE_FLAGS


def test_another_processor_builds_its_own_library(
        cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    function = _rk4_function()
    here = compiled_library("native_probe", [function], key="probe shared")
    assert compiled_library("native_probe", [function], key="probe shared") == here
    monkeypatch.setattr(compiled, "host_processor", lambda: "another processor | avx9")
    there = compiled_library("native_probe", [function], key="probe shared")
    assert here is not None and there is not None and there != here
    assert len(list(cache.iterdir())) == 2


def test_the_key_holds_the_processors_instruction_sets() -> None:
    described = compiled.host_processor()
    assert described.strip()
    info = Path("/proc/cpuinfo")
    if not info.is_file():
        pytest.skip("no /proc/cpuinfo: the platform's names stand for the processor")
    sets = [line.partition(":")[2].strip() for line in info.read_text().splitlines()
            if line.split(":")[0].strip() in ("flags", "Features")]
    assert sets and sets[0] in described
