"""The C of every library computes each repeated subexpression once, with the numbers of
the graph as built (:func:`cosim.core.compiled_function.subexpressions_shared`)."""

from __future__ import annotations

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


def _stage_cost_and_dynamics() -> ca.Function:
    """A stage as the NMPC writes one: the heading's cosine and sine formed once for the
    dynamics and again for the cost, and the Lagrangian's Hessian of both (where the
    derivatives repeat the products of every term)."""
    x = ca.SX.sym("x", 3)  # position, heading
    u = ca.SX.sym("u", 2)  # speed, yaw rate
    lam = ca.SX.sym("lam", 3)
    dt = 0.05
    moved = x + dt * ca.vertcat(u[0] * ca.cos(x[2]), u[0] * ca.sin(x[2]), u[1])
    lateral_error = -ca.sin(x[2]) * x[0] + ca.cos(x[2]) * x[1]
    lagrangian = 10.0 * lateral_error ** 2 + ca.dot(lam, moved) + ca.exp(-u[0]) * u[1] ** 2
    z = ca.vertcat(x, u)
    hessian = ca.densify(ca.hessian(lagrangian, z)[0])
    return ca.Function("stage_probe", [z, lam], [moved, hessian], ["z", "lam"],
                       ["moved", "hessian"])




def test_shared_subexpressions_are_fewer_operations_with_the_same_numbers() -> None:
    function = _stage_cost_and_dynamics()
    shared = compiled.subexpressions_shared(function)
    assert shared.n_instructions() < function.n_instructions()
    assert (shared.name(), shared.name_in(), shared.name_out()) == \
        (function.name(), function.name_in(), function.name_out())
    points = np.random.default_rng(3).normal(size=(100, 8)) * 2.0
    for point in points:
        args = [point[:5], point[5:]]
        for ours, built in zip(shared.call(args), function.call(args), strict=True):
            assert np.array_equal(np.asarray(ours), np.asarray(built))


def test_the_library_computes_the_numbers_of_one_without_sharing(
        cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    function = _stage_cost_and_dynamics()
    generated: dict[str, int] = {}

    def measured(name: str) -> Path:
        library = compiled_library(name, [function])
        assert library is not None
        source = ca.CodeGenerator(f"{name}.c")
        source.add(compiled.subexpressions_shared(function))
        generated[name] = len(source.dump())
        return library

    shared = measured("shared_probe")
    monkeypatch.setattr(compiled, "subexpressions_shared", lambda f: f)
    as_built = measured("as_built_probe")
    assert generated["shared_probe"] < generated["as_built_probe"]
    points = np.random.default_rng(5).normal(size=(200, 8)) * 2.0
    assert np.array_equal(evaluated_at(shared, function, points),
                          evaluated_at(as_built, function, points))


def test_a_function_that_is_no_flat_graph_is_generated_as_it_is() -> None:
    x = ca.MX.sym("x", 2)
    function = ca.Function("mx_probe", [x], [ca.sin(x) * ca.sin(x)])
    assert compiled.subexpressions_shared(function) is function


def test_a_function_shared_where_it_is_built_is_generated_once_for_its_callers() -> None:
    # A flat graph built with its subexpressions shared is returned itself, so that a
    # function calling it (an MX graph, generated as it is) and the library's own export
    # name one function, and the C holds its body once (a copy was a second function).
    inner = _stage_cost_and_dynamics()
    z, lam = inner.sx_in()
    shared = ca.Function(inner.name(), [z, lam], inner.call([z, lam]), inner.name_in(),
                         inner.name_out(), {"cse": True})
    assert compiled.subexpressions_shared(shared) is shared
    assert compiled.subexpressions_shared(inner) is not inner

    def bodies(called: ca.Function) -> int:
        zz, ll = ca.MX.sym("z", 5), ca.MX.sym("lam", 3)
        moved, hessian = called(zz, ll)
        caller = ca.Function("caller_probe", [zz, ll], [moved, ca.trace(hessian)])
        source = ca.CodeGenerator("probe.c")
        for function in (called, caller):
            source.add(compiled.subexpressions_shared(function))
        return source.dump().count(f"/* {called.name()}:(")

    assert bodies(shared) == 1
    assert bodies(inner) == 2  # the graph as built: its shared copy and itself
