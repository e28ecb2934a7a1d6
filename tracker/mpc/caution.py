"""Caution: a calmer steering wheel while the estimate is unsure where the car is.

A controller that treats the estimate as the truth (certainty equivalence) steers as hard
against an error the filter is unsure of as against one it knows; a cautious controller
holds back where the uncertainty is large (cautious control: Astrom and Wittenmark,
"Adaptive Control", 2nd ed., Addison-Wesley 1995, on the stochastic adaptive controllers;
Bar-Shalom and Tse, "Dual effect, certainty equivalence, and separation in stochastic
control", IEEE TAC 19(5), 1974). Here the NMPCs and the LTV-MPC scale the steering-rate weight
of each solve by the estimate's standard deviation across the car's heading::

    w_steer_rate' = w_steer_rate (1 + sigma_lat^2 / sigma_0^2),
    sigma_lat^2   = n' P_xy n,  n = (-sin psi, cos psi)

with ``P_xy`` the estimate's position covariance, ``psi`` its yaw and ``sigma_0``
``tracker.caution_lateral_sigma_m``. With an RTK receiver (``sigma_lat`` about 1 cm) the
weight is the configured one to a few per cent; while the filter converges from its
prior (0.5 m) or with a receiver of metre-class noise (``gnss``: about 0.18 m), it is
ten to seventy times larger: the wheel does not chase the estimate's convergence. The
weights are parameters of the NLP (:mod:`tracker.mpc.nmpc_problem`) and the LTV-MPC's QP
(:mod:`tracker.mpc.ltv_qp`), so this costs no build.
Why: docs/defaults.md, the NMPCs' weights.
"""

from __future__ import annotations

import math

import numpy as np

from cosim.core.records import Estimate


def lateral_variance_m2(estimate: Estimate) -> float:
    """The estimate's position variance across its own heading, ``n' P_xy n`` [m^2]; NaN
    where the estimate has no position or heading."""
    names = estimate.names
    if not ("x_m" in names and "y_m" in names and "yaw_rad" in names):
        return math.nan
    position = estimate.sub_covariance(("x_m", "y_m"))
    yaw = estimate["yaw_rad"]
    normal = np.array([-math.sin(yaw), math.cos(yaw)])
    return float(normal @ position @ normal)


def steer_rate_factor(estimate: Estimate, sigma_0_m: float) -> float:
    """``1 + sigma_lat^2 / sigma_0^2`` (module docstring); 1 with ``sigma_0_m`` 0 (off) and
    where the variance is not a finite non-negative number (no position in the estimate, or
    a broken covariance: the start's own checks deal with that)."""
    if sigma_0_m <= 0.0:
        return 1.0
    variance = lateral_variance_m2(estimate)
    if not (math.isfinite(variance) and variance >= 0.0):
        return 1.0
    return 1.0 + variance / sigma_0_m**2
