"""Monte Carlo consistency of a filter: ANEES per time step and NIS per degree of freedom.

A filter is consistent when its errors are as large as its covariance says. Bar-Shalom, Li,
Kirubarajan, "Estimation with Applications to Tracking and Navigation", Wiley 2001,
section 5.4, test it over an ensemble of ``N`` independent runs (Monte Carlo: same
scenario, independent noise):

- NEES ``e_k' P_k^-1 e_k`` of an ``n``-dimensional error is chi-square with ``n`` degrees
  of freedom at every time step ``k``; the *average over the runs at that step*, the ANEES,
  times ``N`` is chi-square with ``N n`` degrees of freedom (the runs are independent), so
  with probability ``p`` it lies in ``[chi2_((1-p)/2)(N n), chi2_((1+p)/2)(N n)] / N``
  (eq. 5.4.2-5). A consistent filter has about a fraction ``p`` of its steps inside; too
  few steps inside and the filter is over-confident (above) or under-confident (below).
- NIS ``y' S^-1 y`` of an ``m``-channel innovation is chi-square with ``m`` degrees of
  freedom, and a consistent filter's innovations are white in time (section 5.4.2), so the
  NIS summed over all of a sensor's updates, divided by their summed channels, is the NIS
  per degree of freedom: 1, with a band ``chi2(M)/M`` for ``M`` summed channels.

What is *not* a test: the time average of one run's NEES (``nees_mean``) treated as one
chi-square draw. Its ~1,500 samples are strongly correlated (an autocorrelation time of
some 50 samples), so it is neither chi-square with 4 nor with 6,000 degrees of freedom, and
a band of either kind is wrong (the first 4-5 times too wide).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

NEES_DOF = 4
"""Degrees of freedom of the runs' NEES: x, y, yaw, vx
(:data:`cosim.simulation.metrics.NEES_STATES`)."""

SETTLE_S = 1.0
"""ANEES is judged after this time: the first second is the prior's convergence."""


def nees_band(dof: int, runs: int, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided ``probability`` band of the ANEES over ``runs`` independent runs of a
    consistent filter with a ``dof``-dimensional error, at one time step (eq. 5.4.2-5)."""
    if dof < 1 or runs < 1:
        raise ValueError(f"dof = {dof}, runs = {runs}: expected both >= 1")
    return chi_square_band(dof * runs, probability, scale=runs)


def chi_square_band(
    dof: int, probability: float = 0.95, scale: float | None = None
) -> tuple[float, float]:
    """Two-sided ``probability`` interval of a chi-square(``dof``) variable divided by
    ``scale`` (default ``dof``: the band of a per-degree-of-freedom average)."""
    if dof < 1:
        raise ValueError(f"dof = {dof}: expected >= 1")
    if not 0.0 < probability < 1.0:
        raise ValueError(f"probability = {probability!r}: expected a number in (0, 1)")
    divisor = float(dof if scale is None else scale)
    tail = 0.5 * (1.0 - probability)
    return chi_square_quantile(tail, dof) / divisor, chi_square_quantile(1.0 - tail, dof) / divisor


def chi_square_quantile(probability: float, dof: int) -> float:
    """The ``probability`` quantile of a chi-square(``dof``) variable (what
    ``scipy.stats.chi2.ppf`` gives, to about 1e-13; without scipy, a fifth of a second of
    every start for the filter's gate).

    The distribution function is ``P(k/2, x/2)``, the regularised lower incomplete gamma
    function, which for an integer ``k`` has closed forms (Abramowitz, Stegun, "Handbook of
    Mathematical Functions", 1964, 26.4.4-5 and 6.5.13): with ``y = x/2`` and ``k = 2m``
    (even) or ``2m + 1`` (odd), the upper tail ``Q = 1 - P`` is

        Q = exp(-y) sum_{i<m} y^i / i!                       (k even)
        Q = erfc(sqrt y) + exp(-y) sum_{i<m} y^(i+1/2) / Gamma(i+3/2)   (k odd),

    used where ``y >= k/2 + 1``; below, the series ``P = exp(-y) y^a / Gamma(a+1) sum_n
    y^n / ((a+1)..(a+n))`` with ``a = k/2`` (6.5.29) keeps a small ``P`` accurate. The
    quantile is found by Newton's method on whichever tail is the smaller (the density
    ``x^(a-1) exp(-x/2) / (2^a Gamma(a))`` its derivative), from the Wilson-Hilferty
    approximation, inside a bracket that halves when a step would leave it.
    """
    if isinstance(dof, bool) or not isinstance(dof, int) or dof < 1:
        raise ValueError(f"dof = {dof!r}: expected an integer >= 1")
    if not 0.0 < probability < 1.0:
        raise ValueError(f"probability = {probability!r}: expected a number in (0, 1)")
    upper = probability > 0.5
    target = 1.0 - probability if upper else probability
    a = 0.5 * dof
    z = NormalDist().inv_cdf(probability)
    c = 2.0 / (9.0 * dof)
    x = dof * max(1.0 - c + z * math.sqrt(c), 0.0) ** 3
    if not x > 0.0:  # far in the lower tail: P ~ (x/2)^a / Gamma(a+1)
        x = 2.0 * math.exp((math.log(target) + math.lgamma(a + 1.0)) / a)
    low, high = 0.0, math.inf
    for _ in range(200):
        lower_tail, upper_tail = _chi_square_tails(x, dof)
        error = (upper_tail - target) if upper else (lower_tail - target)
        below = error > 0.0 if upper else error < 0.0  # the quantile is above x
        if below:
            low = x
        else:
            high = x
        density = math.exp((a - 1.0) * math.log(x) - 0.5 * x - a * math.log(2.0)
                           - math.lgamma(a))
        step = (error if upper else -error) / density
        candidate = x + step
        if not low < candidate < high:
            candidate = 0.5 * (low + high) if math.isfinite(high) else 2.0 * x
        if abs(candidate - x) <= 4e-16 * x:
            return candidate
        x = candidate
    return x


def _chi_square_tails(x: float, dof: int) -> tuple[float, float]:
    """``(P, Q)``: the lower and upper tails of chi-square(``dof``) at ``x > 0``
    (:func:`chi_square_quantile`)."""
    a, y = 0.5 * dof, 0.5 * x
    log_y = math.log(y)
    if y < a + 1.0:
        term = total = 1.0
        n = 1
        while term > 1e-17 * total:
            term *= y / (a + n)
            total += term
            n += 1
        lower = math.exp(a * log_y - y - math.lgamma(a + 1.0)) * total
        return lower, 1.0 - lower
    m, odd = divmod(dof, 2)
    shift = 0.5 if odd else 0.0
    upper = math.erfc(math.sqrt(y)) if odd else 0.0
    for i in range(m):
        upper += math.exp((i + shift) * log_y - y - math.lgamma(i + shift + 1.0))
    return 1.0 - upper, upper


def window_means(t_s: np.ndarray, values: np.ndarray, start_s: float,
                 window_s: float) -> list[tuple[float, float]]:
    """``(start, mean of values)`` of consecutive windows ``[start, start + window_s)`` of the
    times ``t_s`` from ``start_s`` on; a last window shorter than half of ``window_s`` is
    left out."""
    if window_s <= 0.0:
        raise ValueError(f"window_s = {window_s!r}: expected a positive duration")
    means = []
    start = start_s
    while start + 0.5 * window_s <= float(t_s[-1]) + 1e-9:
        inside = (t_s >= start - 1e-9) & (t_s < start + window_s - 1e-9)
        if inside.any():
            means.append((start, float(np.mean(values[inside]))))
        start += window_s
    return means


@dataclass(frozen=True)
class SensorNis:
    """A sensor's NIS over an ensemble: summed NIS per summed degree of freedom."""

    nis_per_dof: float
    dof: int
    band: tuple[float, float]
    """The ``probability`` band of a consistent filter's NIS per dof with ``dof`` channels."""


@dataclass(frozen=True)
class EnsembleConsistency:
    """The consistency figures of a Monte Carlo ensemble (see the module docstring)."""

    runs: int
    dof: int
    probability: float
    t_s: np.ndarray
    """Time of every judged step (after :data:`SETTLE_S`)."""
    anees: np.ndarray
    """ANEES at each judged step."""
    band: tuple[float, float]
    fraction_inside: float
    fraction_below: float
    fraction_above: float
    nis: Mapping[str, SensorNis]

    def worst_window_above(self, window_s: float = 1.0) -> float:
        """The largest fraction of steps above the band in any window ``[t, t + window_s)``
        of the judged steps (one starting at every judged step that has a whole window after
        it): a filter over-confident in one part of the manoeuvre only (a swerve) shows here
        while its overall fraction above stays small."""
        if window_s <= 0.0:
            raise ValueError(f"window_s = {window_s!r}: expected a positive duration")
        above = (self.anees > self.band[1]).astype(float)
        cumulative = np.concatenate(([0.0], np.cumsum(above)))
        starts = np.flatnonzero(self.t_s + window_s <= self.t_s[-1] + 1e-9)
        if not starts.size:  # shorter than one window: the whole judged span
            return float(above.mean())
        ends = np.searchsorted(self.t_s, self.t_s[starts] + window_s - 1e-9)
        return float(np.max((cumulative[ends] - cumulative[starts]) / (ends - starts)))

    @property
    def anees_mean(self) -> float:
        """The ANEES averaged over the judged steps (a summary, not the test)."""
        return float(np.mean(self.anees))

    def window_means(self, window_s: float = 1.0) -> list[tuple[float, float]]:
        """``(start_s, mean ANEES)`` of consecutive windows ``[start, start + window_s)`` from
        the first judged step on (a last window shorter than half of ``window_s`` is left
        out): the shape of the filter's confidence over the manoeuvre, over-confident where
        a window's mean lies above the band, under-confident below it."""
        return window_means(self.t_s, self.anees, float(self.t_s[0]), window_s)

    def consistent(
        self, min_fraction: float = 0.9, nis_range: tuple[float, float] = (0.9, 1.1)
    ) -> bool:
        """ANEES inside its band at ``min_fraction`` of the steps, at most half of the rest
        on either side of it, and every sensor's NIS per dof in ``nis_range`` (the default
        0.9-1.1: on the lane change's `gnss` ensemble of the tests the filter's own sensors
        settle at 0.97-1.03; all its process noise x3 takes the IMU's to 0.88, x0.3 to
        1.15, while a 20-run ANEES band, 2.86-5.33, holds 91 and 97 % of their steps).

        A consistent filter leaves ``(1 - p) / 2`` of its steps on each side of the band;
        the check allows twice ``1 - p`` outside in all and twice ``(1 - p) / 2`` on each
        side: over-confidence (above) and under-confidence (below) are failures of their
        own, and neither hides in the allowance the other did not use."""
        low, high = nis_range
        tail = 0.5 * (1.0 - min_fraction)
        return (self.fraction_inside >= min_fraction
                and max(self.fraction_above, self.fraction_below) <= tail
                and all(low <= s.nis_per_dof <= high for s in self.nis.values()))

    def lines(self) -> list[str]:
        """A human-readable report."""
        low, high = self.band
        result = [
            f"ANEES ({self.dof} dof, {self.runs} runs, {self.t_s.size} steps after "
            f"{SETTLE_S:g} s): {100 * self.probability:g} % band [{low:.3f}, {high:.3f}], "
            f"inside {100 * self.fraction_inside:.1f} % (below {100 * self.fraction_below:.1f}"
            f" %, above {100 * self.fraction_above:.1f} %), mean {self.anees_mean:.3f}, "
            f"median {float(np.median(self.anees)):.3f}",
        ]
        for sensor, figures in sorted(self.nis.items()):
            result.append(
                f"NIS/dof {sensor:12s} {figures.nis_per_dof:7.3f}   ({figures.dof} dof; "
                f"band [{figures.band[0]:.3f}, {figures.band[1]:.3f}])"
            )
        return result


def ensemble_consistency(
    t_s: np.ndarray,
    nees: np.ndarray,
    nis_sums: Sequence[Mapping[str, float]],
    nis_dofs: Sequence[Mapping[str, int]],
    *,
    dof: int = NEES_DOF,
    probability: float = 0.95,
    settle_s: float = SETTLE_S,
) -> EnsembleConsistency:
    """The figures of an ensemble: ``nees`` has one row per run and one column per time
    ``t_s`` (every run sampled at the same times); ``nis_sums``/``nis_dofs`` give per run and
    sensor the summed NIS and summed channels of every tested update."""
    t_s = np.asarray(t_s, dtype=float)
    nees = np.atleast_2d(np.asarray(nees, dtype=float))
    runs = nees.shape[0]
    if nees.shape[1] != t_s.size:
        raise ValueError(f"nees of shape {nees.shape}: expected {t_s.size} columns")
    if len(nis_sums) != runs or len(nis_dofs) != runs:
        raise ValueError(f"{runs} runs of NEES but {len(nis_sums)} of NIS")
    judged = t_s >= settle_s
    if not judged.any():
        raise ValueError(f"no time step at or after {settle_s} s")
    if not np.isfinite(nees[:, judged]).all():
        raise ValueError("a run has a non-finite NEES after the settling time")
    anees = nees[:, judged].mean(axis=0)
    low, high = nees_band(dof, runs, probability)
    nis: dict[str, SensorNis] = {}
    for sensor in sorted({s for sums in nis_sums for s in sums}):
        total = float(sum(sums.get(sensor, 0.0) for sums in nis_sums))
        count = int(sum(dofs.get(sensor, 0) for dofs in nis_dofs))
        if count:
            nis[sensor] = SensorNis(total / count, count, chi_square_band(count, probability))
    return EnsembleConsistency(
        runs=runs,
        dof=dof,
        probability=probability,
        t_s=t_s[judged],
        anees=anees,
        band=(low, high),
        fraction_inside=float(np.mean((anees >= low) & (anees <= high))),
        fraction_below=float(np.mean(anees < low)),
        fraction_above=float(np.mean(anees > high)),
        nis=nis,
    )


def anees_standard_error(t_s: np.ndarray, nees: np.ndarray, *,
                         settle_s: float = SETTLE_S) -> tuple[float, float]:
    """The standard error of the ensemble's mean ANEES after ``settle_s`` from the spread of
    the runs' own mean NEES (``std / sqrt(runs)``), and what it would be were every step of
    every run an independent chi-square draw, ``sqrt(2 dof / (steps runs))``.

    The band assumes independent draws across runs at each step, which they are; a run's
    steps are not: its NEES is correlated over the whole run (its sampled initial errors and
    biases, the slow states), so one run high or low moves many steps at once. The first
    figure over the second says how much more of a mean ANEES, and of the fraction of steps
    inside the band, is the seeds' than the band's width suggests."""
    t_s = np.asarray(t_s, dtype=float)
    judged = np.atleast_2d(np.asarray(nees, dtype=float))[:, t_s >= settle_s]
    runs, steps = judged.shape
    if runs < 2 or steps < 1:
        raise ValueError(f"{runs} runs of {steps} steps after {settle_s} s: expected at "
                         "least two runs and one step")
    run_means = judged.mean(axis=1)
    return (float(np.std(run_means, ddof=1) / math.sqrt(runs)),
            math.sqrt(2.0 * NEES_DOF / (steps * runs)))


@dataclass(frozen=True)
class FalseAlarms:
    """What a consistent filter's gate refuses by chance among ``tested`` updates
    (:func:`false_alarms`)."""

    tested: int
    expected: float
    """``tested (1 - gate_probability)``."""
    at_most: int
    """The count a consistent filter stays at or below with the probability asked for."""


def false_alarms(tested: int, gate_probability: float,
                 probability: float = 0.95) -> FalseAlarms:
    """How many of ``tested`` updates a *consistent* filter's NIS gate refuses.

    Each update's NIS is chi-square with its channels as degrees of freedom, and the gate is
    that distribution's ``gate_probability`` quantile, so each update is refused with
    probability ``q = 1 - gate_probability`` whatever its dimension; independent innovations
    (white, Bar-Shalom, Li, Kirubarajan 2001, section 5.4.2) make the count binomial
    ``B(tested, q)``. ``at_most`` is its ``probability`` quantile: a count above it says the
    filter is wrong where it was gated, a count at or below it is what the gate does to a
    right one. (With the default gate, 0.9999, a hundred lane changes test some 22,000
    updates in their first second: a consistent filter has some 2 refused.)"""
    if tested < 0:
        raise ValueError(f"tested = {tested}: expected a count >= 0")
    if not 0.0 < gate_probability < 1.0:
        raise ValueError(f"gate_probability = {gate_probability!r}: expected in (0, 1)")
    if not 0.0 < probability < 1.0:
        raise ValueError(f"probability = {probability!r}: expected in (0, 1)")
    q = 1.0 - gate_probability
    term = math.exp(tested * math.log1p(-q))  # P(count = 0)
    cumulative, count = term, 0
    while cumulative < probability and count < tested:
        term *= (tested - count) / (count + 1) * q / (1.0 - q)
        count += 1
        cumulative += term
    return FalseAlarms(tested, tested * q, count)
