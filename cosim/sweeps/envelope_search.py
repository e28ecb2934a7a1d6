"""Where a requirement starts to fail: root-finding on its robustness along rays from the
nominal point, over a seed ensemble (the search of ``cosim envelope``).

A grid answers "how wrong can the model be?" to one grid step with N^d runs. The
robustness of an STL requirement (:mod:`cosim.simulation.requirements`) is a continuous
measure of how far a run is from violating it, so its zero can be searched for instead, as
falsification tools for cyber-physical systems search theirs (Annpureddy et al., "S-TaLiRo:
A Tool for Temporal Logic Falsification for Hybrid Systems", TACAS 2011; Donze, "Breach, A
Toolbox for Verification and Parameter Synthesis of Hybrid Systems", CAV 2010).

The search space is a box of mismatch parameters, each from its nominal value (where the
requirement must hold) to a search limit. A *ray* goes from the nominal point to the box's
far edge; along it, ``s`` in [0, 1] is the fraction of the way. For each ray and each seed
a :class:`Bracket` keeps the largest ``s`` that passed and the smallest that failed:

1. ``s = 0`` (nominal) and ``s = 1`` (the limit) first: a seed that fails at nominal has
   critical ``s = 0``; one that passes at the limit holds over the whole ray (``s = inf``);
2. then regula falsi with the Illinois modification (Dowell and Jarratt, BIT 11, 1971) on
   the robustness while both ends have one, bisection when the failing end has none (a run
   that spun or stopped: its robustness covers part of the run, so it counts as a failure
   with no value), each step kept inside the middle 80 % of the bracket so a flat or
   discontinuous robustness costs no more than bisection;
3. until the bracket is narrower than the resolution; the critical ``s`` is its middle.

A run passes when its outcome is ``ok`` and its robustness is >= 0. Each seed's critical
value is the first crossing the bracketing finds from the nominal point: a seed whose
robustness is not monotone along the ray may fail again further out. The ensemble's
boundary at a failure level ``q`` is where the share of seeds with a critical value at or
below it first exceeds ``q``: the k-th smallest critical value, k = floor(q n) + 1.

Two parameters: rays at angles between the two axes in the box scaled to [0, 1]^2, first
at :data:`FIRST_RAYS` angles, then a ray between two neighbours wherever their boundary
points lie further apart than the resolution allows (:func:`rays_to_add`), so the runs go
where the boundary is.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

FIRST_RAYS = 5
"""Rays of the first pass over two parameters (0, 22.5, 45, 67.5, 90 degrees)."""

INNER = 0.1
"""A regula falsi step lands at least this fraction of the bracket from either end."""


@dataclass(frozen=True)
class Ray:
    """From the nominal point towards ``direction`` (each parameter's share of the way from
    its nominal value to its limit) until the box's edge."""

    angle_deg: float
    direction: tuple[float, ...]
    """The point at ``s = 1``, in box units (0 nominal, 1 the limit, per parameter)."""

    def unit_point(self, s: float) -> tuple[float, ...]:
        return tuple(s * d for d in self.direction)


def axis_ray(n_parameters: int, axis: int) -> Ray:
    """The ray along one parameter alone (the others at nominal)."""
    return Ray(90.0 * axis, tuple(1.0 if i == axis else 0.0 for i in range(n_parameters)))


def plane_ray(angle_deg: float) -> Ray:
    """A ray of the two-parameter box at ``angle_deg`` from the first axis, to its edge."""
    u = (math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg)))
    u = tuple(0.0 if abs(c) < 1e-12 else c for c in u)
    reach = 1.0 / max(u)
    return Ray(angle_deg, (u[0] * reach, u[1] * reach))


@dataclass
class Bracket:
    """The search along one ray for one seed."""

    resolution: float
    """Stop when the bracket is narrower than this (in ``s``)."""
    passed_s: float | None = None
    passed_score: float = math.nan
    failed_s: float | None = None
    failed_score: float = math.nan
    """The failing end's robustness (NaN: a run that stopped, no value)."""
    _side_kept: int = 0
    """Illinois: how many steps in a row kept the same end (its score is then halved)."""
    evaluated: list[tuple[float, float, bool]] = field(default_factory=list)
    """Every (s, robustness, passed) of this bracket, in order."""

    def next_s(self) -> float | None:
        """The next ``s`` to run, or None when the search along this ray is over."""
        if self.passed_s is None and self.failed_s is None:
            return 0.0
        if self.passed_s is None:
            return None  # fails at nominal
        if self.failed_s is None:
            return 1.0 if self.passed_s < 1.0 else None  # the limit, or holds throughout
        lo, hi = self.passed_s, self.failed_s
        if hi - lo <= self.resolution:
            return None
        if math.isfinite(self.failed_score) and math.isfinite(self.passed_score) \
                and self.passed_score > self.failed_score:
            # Illinois: the end kept twice in a row counts half, so the other end moves.
            weight_lo = self.passed_score / (2.0 if self._side_kept > 1 else 1.0)
            weight_hi = self.failed_score / (2.0 if self._side_kept < -1 else 1.0)
            s = lo + weight_lo * (hi - lo) / (weight_lo - weight_hi)
        else:
            s = 0.5 * (lo + hi)
        return min(max(s, lo + INNER * (hi - lo)), hi - INNER * (hi - lo))

    def record(self, s: float, score: float, passed: bool) -> None:
        """The run at ``s``: its robustness (NaN if none) and whether it passed."""
        self.evaluated.append((s, score, passed))
        if passed:
            self.passed_s, self.passed_score = s, score
            self._side_kept = self._side_kept - 1 if self._side_kept < 0 else -1
        else:
            self.failed_s, self.failed_score = s, score
            self._side_kept = self._side_kept + 1 if self._side_kept > 0 else 1

    @property
    def critical_s(self) -> float:
        """Where the requirement starts to fail: 0 at nominal, inf beyond the limit."""
        if self.passed_s is None:
            return 0.0
        if self.failed_s is None:
            return math.inf
        return 0.5 * (self.passed_s + self.failed_s)


def ensemble_boundary(critical: Sequence[float], failure_rate: float) -> float:
    """The ``s`` where the share of seeds failing first exceeds ``failure_rate``: the k-th
    smallest critical value, k = floor(failure_rate * n) + 1 (inf if that many seeds hold
    over the whole ray)."""
    ordered = sorted(critical)
    k = min(len(ordered), math.floor(failure_rate * len(ordered)) + 1)
    return ordered[k - 1]


def rays_to_add(rays: Sequence[Ray], boundary_s: Sequence[float], spacing: float,
                max_rays: int) -> list[Ray]:
    """New rays between neighbours (by angle) whose boundary points are further apart
    than ``spacing`` in box units (a side that holds throughout is at the box's edge);
    none beyond ``max_rays`` in all."""
    order = sorted(range(len(rays)), key=lambda i: rays[i].angle_deg)
    new: list[Ray] = []
    for a, b in zip(order, order[1:], strict=False):
        pa = rays[a].unit_point(min(boundary_s[a], 1.0))
        pb = rays[b].unit_point(min(boundary_s[b], 1.0))
        if math.dist(pa, pb) > spacing and rays[b].angle_deg - rays[a].angle_deg > 0.5:
            new.append(plane_ray(0.5 * (rays[a].angle_deg + rays[b].angle_deg)))
    return new[:max(0, max_rays - len(rays))]
