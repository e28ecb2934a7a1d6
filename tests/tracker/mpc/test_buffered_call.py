"""A solver called through its buffer (tracker.mpc.nlp.BufferedNlpCall) gives what a call
with a dict gives, to the bit, bounds that move from solve to solve included."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from tracker.mpc.nlp import BufferedNlpCall


def _qp(plugin: str) -> ca.Function:
    """A small parametric QP with bounds on the variables and a coupling constraint."""
    x, p = ca.SX.sym("x", 4), ca.SX.sym("p", 4)
    cost = ca.sumsqr(x - p) + 0.3 * x[0] * x[1] + 0.1 * ca.sumsqr(ca.diff(x))
    g = ca.vertcat(x[0] + x[1] + x[2], x[2] - x[3])
    return ca.qpsol(f"qp_{plugin}", plugin, {"x": x, "p": p, "f": cost, "g": g},
                    {"error_on_fail": False, "print_time": False,
                     **({"printLevel": "none"} if plugin == "qpoases" else {}),
                     **({"osqp": {"verbose": False}} if plugin == "osqp" else {})})


@pytest.mark.parametrize("plugin", ["qrqp", "osqp", "highs"])
def test_the_buffered_call_is_the_dict_call(plugin: str) -> None:
    """Six solves in a row, each against the same solves called with a dict on a twin
    solver: a solver with memory (osqp warm-starts from its last solve) has the same
    history in both, as a tracker's one solver has."""
    solver = _qp(plugin)
    lbg, ubg = np.array([-1.0, -0.5]), np.array([1.0, 0.5])
    call = BufferedNlpCall(_qp(plugin), {"lbg": lbg, "ubg": ubg})
    rng = np.random.default_rng(5)
    for k in range(6):
        params = rng.normal(size=4) * 2.0
        lbx, ubx = -np.abs(rng.normal(size=4)) - 0.2, np.abs(rng.normal(size=4)) + 0.2
        if k % 2:  # a solve whose bounds bind everywhere they can
            lbx, ubx = lbx * 0.1, ubx * 0.1
        x, f = call(0.0, params, lbx=lbx, ubx=ubx)
        stats = call.stats()
        reference = solver(x0=0.0, p=params, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        assert np.array_equal(x, np.asarray(reference["x"]).ravel())
        assert f == float(reference["f"])
        assert stats["success"] == solver.stats()["success"]
        assert stats["iter_count"] == solver.stats()["iter_count"]
        assert stats["return_status"] == solver.stats()["return_status"]


def test_bounds_not_given_stay_as_they_were() -> None:
    """The constraint bounds set once hold for every solve; variable bounds given for one
    solve hold for the next until given again."""
    solver = _qp("qrqp")
    call = BufferedNlpCall(solver, {"lbg": [-0.1, -0.1], "ubg": [0.1, 0.1]})
    params = np.array([1.0, 1.0, 1.0, 1.0])
    tight, _ = call(0.0, params, lbx=np.full(4, -0.05), ubx=np.full(4, 0.05))
    again, _ = call(0.0, params)
    assert np.array_equal(tight, again)
    assert np.all(np.abs(again) <= 0.05 + 1e-9)
    loose, _ = call(0.0, params, lbx=np.full(4, -10.0), ubx=np.full(4, 10.0))
    assert abs(loose[0] + loose[1] + loose[2]) <= 0.1 + 1e-9 and np.max(np.abs(loose)) > 0.05
