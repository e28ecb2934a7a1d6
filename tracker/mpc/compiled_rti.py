"""One step of the real-time iteration as one compiled C function, the QP solver included.

A step of :class:`tracker.mpc.nlp.RealTimeIteration` is: evaluate the QP's data at the
iterate ``w`` (Gauss-Newton Hessian, cost gradient, constraints and their Jacobian), solve
the QP for ``dw`` with hpipm, take the full step. :func:`rti_step_function` writes it as one
CasADi function,

    rti_step(w, p, lbx, ubx, lbg, ubg) -> (w + dw, g(w) + J_g(w) dw, f(w + dw), ...)

and CasADi generates C for all of it, hpipm's call included (the generated code links
against the ``libhpipm`` and ``libblasfeo`` that CasADi ships). :class:`CompiledRtiStep`
calls it through :mod:`ctypes` on buffers bound once: a step costs no conversion between
numpy and CasADi matrices (about 30 us each, a dozen a step in the interpreted iteration)
and no call into CasADi's virtual machine. The same function on the same numbers: the
same floating-point operations as the interpreted iteration, so the same iterates
(``tests/tracker/mpc/test_nmpc_solvers.py``).

The bounds are inputs, set once per tracker; the belief and the weights are parameters
(:mod:`tracker.mpc.nmpc_problem`), so one library serves every configuration of a model,
horizon and stage length.
"""

from __future__ import annotations

import ctypes
import hashlib
import inspect
import re
from pathlib import Path

import casadi as ca
import numpy as np

from cosim.core.compiled_function import CompiledFunction


def casadi_folder() -> Path:
    """Where CasADi keeps its shared libraries (hpipm, blasfeo) and their C headers."""
    return Path(ca.__file__).resolve().parent


def hpipm_build_flags() -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The compiler flags (headers) and link flags (libraries, found again at load time
    through the run path) of generated code calling hpipm."""
    folder = casadi_folder()
    return ((f"-I{folder / 'include'}",),
            (f"-L{folder}", "-lhpipm", "-lblasfeo", f"-Wl,-rpath,{folder}"))


def load_hpipm() -> ctypes.CDLL:
    """This CasADi's hpipm (and the blasfeo it needs), loaded: a compiled real-time
    iteration built in another virtualenv with the same CasADi (its run path naming that
    one's folder, perhaps deleted since) then finds it by its soname
    (:func:`cosim.core.compiled_function.compiled_library`'s ``relocatable``)."""
    return ctypes.CDLL(str(casadi_folder() / "libhpipm.so"))


_HPIPM_PROBLEM = "  struct casadi_hpipm_prob p;\n"
_HPIPM_MODE = re.compile(r"^  p\.hpipm_options\.mode = (\d+);$", re.MULTILINE)

def complete_hpipm_options(source: str) -> str:
    """The generated C with hpipm's options complete.

    CasADi 3.8 generates the QP's problem struct on the stack and assigns hpipm's options
    one by one, but not all of them: ``dual_gap_max``, ``lam0_min``, ``t0_min``,
    ``t0_init`` and ``update_fact_exit`` are left as whatever the stack held, so the
    compiled QP solver failed QPs the interpreted one solves. CasADi's interpreted
    interface starts from ``d_ocp_qp_ipm_arg_set_default(mode)`` and overrides the options
    it was given; this edit makes the generated code do the same (the struct zeroed, the
    mode's defaults set, then CasADi's assignments), so both run hpipm with one set of
    options. Raises ``ValueError`` when the source does not look as expected (another
    CasADi version), and the caller keeps the interpreted iteration.
    """
    mode = _HPIPM_MODE.search(source)
    if source.count(_HPIPM_PROBLEM) != 1 or mode is None:
        raise ValueError("the generated hpipm call does not have the expected form")
    complete = (f"{_HPIPM_PROBLEM}  memset(&p, 0, sizeof p);\n"
                f"  d_ocp_qp_ipm_arg_set_default((enum hpipm_mode) {mode.group(1)}, "
                "&p.hpipm_options);\n")
    return source.replace(_HPIPM_PROBLEM, complete)


def hpipm_options_edit_digest() -> str:
    """A hash of :func:`complete_hpipm_options`'s own source, for a cache key: a changed
    edit builds a new library."""
    return hashlib.sha256(inspect.getsource(complete_hpipm_options).encode()).hexdigest()


def rti_step_function(qp_data: ca.Function, qp: ca.Function, cost: ca.Function) -> ca.Function:
    """``rti_step(w, p, lbx, ubx, lbg, ubg)``: one full Gauss-Newton SQP step from ``w``.

    Outputs: the next iterate ``w + dw``; the linearised constraints ``g(w) + J_g(w) dw``
    (to check the step against the bounds); the cost at the next iterate; the QP's
    multipliers, unused, but CasADi 3.8's generated hpipm code writes them whether or not
    they are asked for (a missing output is a null pointer it writes through).
    """
    n_w, n_p = qp_data.nnz_in(0), qp_data.nnz_in(1)
    n_g = qp_data.nnz_out(2)
    w, p = ca.MX.sym("w", n_w), ca.MX.sym("p", n_p)
    lbx, ubx = ca.MX.sym("lbx", n_w), ca.MX.sym("ubx", n_w)
    lbg, ubg = ca.MX.sym("lbg", n_g), ca.MX.sym("ubg", n_g)
    hessian, gradient, g, jacobian = qp_data(w, p)
    step = qp(h=hessian, g=gradient, a=jacobian, lbx=lbx - w, ubx=ubx - w, lba=lbg - g,
              uba=ubg - g)
    w_next = w + step["x"]
    return ca.Function(
        "rti_step", [w, p, lbx, ubx, lbg, ubg],
        [w_next, g + ca.mtimes(jacobian, step["x"]), cost(w_next, p), step["lam_a"],
         step["lam_x"]],
        ["w", "p", "lbx", "ubx", "lbg", "ubg"],
        ["w_next", "g_linear", "cost", "lam_a", "lam_x"])


class CompiledRtiStep:
    """:func:`rti_step_function` as compiled C, bound to its buffers.

    Args:
      library: the loaded shared library holding ``function``.
      function: the step (:func:`rti_step_function`), for its sizes.
      lbx, ubx, lbg, ubg: the NLP's bounds (fixed for the tracker's life).
    """

    def __init__(self, library: ctypes.CDLL, function: ca.Function, lbx: np.ndarray,
                 ubx: np.ndarray, lbg: np.ndarray, ubg: np.ndarray) -> None:
        self._w = np.zeros(function.nnz_in(0))
        self._p = np.zeros(function.nnz_in(1))
        bounds = [np.array(b, dtype=float) for b in (lbx, ubx, lbg, ubg)]
        self._w_next = np.zeros(function.nnz_out(0))
        self._g_linear = np.zeros(function.nnz_out(1))
        self._cost = np.zeros(1)
        multipliers = [np.zeros(function.nnz_out(3)), np.zeros(function.nnz_out(4))]
        self._function = CompiledFunction(
            library, function, [self._w, self._p, *bounds],
            [self._w_next, self._g_linear, self._cost, *multipliers])

    def __call__(self, w: np.ndarray, params: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, float] | None:
        """The next iterate, the linearised constraints and the cost there; None when
        hpipm found no solution of the QP (the generated code reports only that)."""
        self._w[:] = w
        self._p[:] = params
        if self._function.status_of_call():
            return None
        return self._w_next.copy(), self._g_linear.copy(), float(self._cost[0])
