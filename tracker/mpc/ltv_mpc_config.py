"""Settings of the ``ltv-mpc`` tracker: ``tracker.ltv_mpc`` (Falcone et al. 2007, sec. IV).

Defaults, measured on the MuJoCo sedan (stretched lane change, EKF, seeds 0-4) and on the
QPs of the bench in ``tests/tracker/mpc/test_ltv_mpc.py``; details in :mod:`tracker.mpc.ltv_mpc`:

* ``qp_solver = hpipm`` on the sparse QP: the fastest that never failed, 0.52 ms per solve
  median on the bench's QPs (0.64-0.70 ms on the plant), 4 interior-point iterations.
  qpOASES (condensed) is as fast in the median (0.53 ms) but slower on the first steps
  (115 working-set changes from a cold start) and prints its licence banner to stdout
  twice per tracker; qrqp (condensed) 0.85 ms with a 4.8 ms tail; OSQP (condensed) 1.0 ms.
  On the sparse QP OSQP and qrqp take 1.7 ms, and OSQP fails often at tolerances below
  1e-6; on the condensed QP HPIPM cannot run (it solves stage-wise problems only).
* ``linearise_about = previous-plan`` (real-time iteration): as good as the reference on
  the lane change, better from a large heading error.
* ``slip_limits = true``: as ``dynamic-nmpc``'s, they never bind at 0.5 g and keep the car
  from spinning on Falcone's unstretched path, for 0.13 ms more per solve.
* ``qp_tolerance = 1e-8``: HPIPM's commands then agree with the active-set solvers' to
  1e-5; at 1e-10 HPIPM no longer converges.
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.config_fields import setting
from cosim.core.exceptions import ConfigError

QP_SOLVERS: tuple[str, ...] = ("hpipm", "osqp", "qrqp", "qpoases")
"""CasADi QP back-ends (``conic`` plugins) the LTV-MPC can use."""

QP_FORMULATIONS: tuple[str, ...] = ("auto", "sparse", "condensed")
"""How the QP is posed (:mod:`tracker.mpc.ltv_qp`): states and inputs as variables with the
model as equality constraints (sparse), or the states eliminated (condensed); ``auto``
picks the one the back-end is fastest on (:data:`AUTO_FORMULATION`)."""

AUTO_FORMULATION = {"hpipm": "sparse", "osqp": "condensed", "qrqp": "condensed",
                    "qpoases": "condensed"}
"""The formulation ``auto`` picks per back-end: HPIPM needs the sparse, stage-wise form;
the active-set solvers and OSQP are fastest and most reliable on the small dense one."""

LINEARISATION_POINTS: tuple[str, ...] = ("reference", "previous-plan")
"""Trajectories the LTV-MPC can linearise about (:mod:`tracker.mpc.ltv_mpc`)."""


@dataclass(frozen=True)
class LtvMpcConfig:
    """The linear time-varying MPC solved as one QP per step (Falcone et al. 2007)."""

    qp_solver: str = setting("hpipm", choices=QP_SOLVERS, doc="CasADi QP back-end")
    formulation: str = setting(
        "auto",
        choices=QP_FORMULATIONS,
        doc="sparse (multiple shooting; hpipm needs it), condensed (inputs only), or auto "
        "(sparse for hpipm, condensed for the others)",
    )
    linearise_about: str = setting(
        "previous-plan",
        choices=LINEARISATION_POINTS,
        doc="trajectory the model is linearised about: the reference path in the steady "
        "turn of its curvature (as Lages and Alves 2006 linearise about the reference), or "
        "the previous plan shifted (real-time iteration)",
    )
    slip_limits: bool = setting(
        True,
        doc="soft limits on the tyres' slip angles, linearised, with slack variables "
        "(weights.limit_excess), as dynamic-nmpc's",
    )
    qp_max_iterations: int = setting(
        1000, low=1, high=100000, doc="iteration limit of the QP back-end: interior-point "
        "(hpipm) and active-set (qrqp; working-set changes for qpoases) iterations, under 20 "
        "here; ADMM iterations for osqp, which needs several hundred at qp_tolerance = 1e-8"
    )
    qp_tolerance: float = setting(
        1e-8, low=1e-12, high=1e-2, doc="convergence tolerance of the QP back-end"
    )

    def __post_init__(self) -> None:
        if self.qp_solver == "hpipm" and self.formulation == "condensed":
            raise ConfigError(
                f"formulation = {self.formulation!r}: qp_solver 'hpipm' solves "
                "optimal-control QPs stage by stage, expected 'sparse' or 'auto'"
            )

    @property
    def qp_formulation(self) -> str:
        """The formulation in use: ``formulation``, or the back-end's if ``auto``."""
        if self.formulation == "auto":
            return AUTO_FORMULATION[self.qp_solver]
        return self.formulation
