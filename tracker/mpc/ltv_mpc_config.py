"""Settings of the ``ltv-mpc`` tracker: ``tracker.ltv_mpc`` (Falcone et al. 2007, sec. IV).

Defaults (the measurements behind them: docs/defaults.md, ``ltv-mpc``):

* ``qp_solver = hpipm`` on the sparse QP: the fastest back-end that never failed on the
  bench's QPs; qpOASES prints its licence banner to stdout, HPIPM cannot run the condensed
  QP (it solves stage-wise problems only).
* ``linearise_about = previous-plan`` (real-time iteration).
* ``slip_limits = true``, as ``dynamic-nmpc``'s.
* ``qp_tolerance = 1e-8``: the tightest at which HPIPM still converges.
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
