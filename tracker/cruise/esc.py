"""Extremum seeking control (ESC): model-free online minimisation of a measured objective.

The perturbation-based scheme of Ariyur and Krstic, "Real-Time Optimization by
Extremum-Seeking Control", Wiley 2003, ch. 1-2 (multi-parameter: ch. 2.3), whose stability
for a plant with dynamics is Krstic and Wang, "Stability of extremum seeking feedback for
general nonlinear dynamic systems", Automatica 36(4), 2000. For each parameter ``i``:

    theta_i(t)   = theta_hat_i(t) + a_i sin(omega_i t)             (modulation)
    eta(t)       = HPF_{omega_h}[J(t)]                             (remove the mean of J)
    xi_i(t)      = LPF_{omega_l}[eta(t) b_i sin(omega_i t)]        (demodulate, average)
    d/dt theta_hat_i = -k_i xi_i                                   (integrate: descent)

Averaged over a period, ``xi_i ~ (a_i b_i / 2) dJ/dtheta_i``, so ``theta_hat`` follows the
gradient downhill at rate ``k_i a_i b_i / 2``. The filters are first order, discretised
exactly for a sample held over ``dt`` (the high-pass is one minus the low-pass of the same
cut-off). Each ``theta_hat_i`` is kept inside ``[low_i, high_i]`` (an ACC gain must stay
positive).

Two options (:class:`EscAdaptation`) for a measured objective that is noisy and whose scale
is not known in advance:

- *Normalised by its mean* (``normalise_by_mean``): ``eta = (J - J_mean) / J_mean`` with
  ``J_mean`` the high-pass filter's own running mean (floored). Averaged, ``xi_i ~ (a_i b_i /
  2) dJ/dtheta_i / J_mean``: a gradient relative to the objective's level, so one step suits
  objectives of 0.1 and of 1000, and the minimiser is that of the mean objective ``E[J]``.
  (Seeking on ``log J`` sample by sample also gives a relative gradient, but it minimises
  ``E[log J]``, which is not ``log E[J]`` when J is noisy: on the ACC the two minimisers
  differ by about 10 % in ``K_vrel``.)
- *A decaying step* (``step_decay_s = T``): channel ``i``'s step is ``k_i / (1 + tau_i /
  T)``, ``tau_i`` the time it has been tuned. With a constant step and a noisy objective the
  estimate never settles: it random-walks about the optimum, and along a direction in which
  the objective is flat it wanders without bound, driven by noise alone. A step that decays
  like ``1 / t`` (its sum diverges, the sum of its squares converges) is the stochastic
  approximation schedule of Kiefer and Wolfowitz, "Stochastic estimation of the maximum of
  a regression function", Annals of Mathematical Statistics 23(3), 1952, under which
  extremum seeking with noisy measurements converges (Stankovic and Stipanovic, "Extremum
  seeking under stochastic noise and applications to mobile sensors", Automatica 46(8),
  2010). Near the optimum the averaged error then shrinks like ``(1 + tau / T)^-(k a b H T
  / 2)`` (``H`` the objective's curvature): a fast approach needs ``k a b H T / 2 > 1``.

The tuning rules (:func:`tuning_breaches`, Ariyur and Krstic 2003, sec. 1.2 and 2.3; Krstic
and Wang 2000, sec. 5):

- each perturbation slower than the plant's mode the parameter acts through (time-scale
  separation: through a plant with phase lag ``phi`` at ``omega`` the demodulated gradient
  is scaled by ``cos phi``, and past 90 degrees it changes sign, so ESC climbs);
- each perturbation above the high-pass and low-pass cut-offs, and below the Nyquist
  frequency of the update rate;
- distinct frequencies, with a low-pass cut-off below their spacing (so the demodulated
  channels do not leak into one another: with the cut-off above the spacing, three channels
  on a quadratic map drive each other to their bounds);
- none the sum of two others or twice another, to within the low-pass cut-off (near the
  optimum the objective is quadratic in the parameters, so it holds ``omega_i + omega_j``
  and ``2 omega_i``; demodulated at one of those, they pass the low-pass as a spurious
  gradient);
- a demodulation amplitude much larger than the modulation amplitude;
- a positive step ``k`` (too large a step makes the loop unstable, which no static check can
  tell).
"""

from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass

from cosim.core.exceptions import ConfigError


class EscTuningWarning(UserWarning):
    """A tuning rule of extremum seeking control is breached (the message names it)."""


@dataclass(frozen=True)
class EscChannel:
    """One tuned parameter: its start, bounds, perturbation and step."""

    name: str
    initial: float
    low: float
    high: float
    amplitude: float
    """Modulation amplitude ``a`` (in the parameter's unit)."""
    frequency_radps: float
    """Perturbation frequency ``omega`` [rad/s]."""
    demodulation_amplitude: float
    """Demodulation amplitude ``b``."""
    step: float
    """Integrator gain ``k``."""
    plant_frequency_radps: float | None = None
    """The frequency of the plant's mode this parameter acts through [rad/s] (tuning rule
    'perturbation slower than the plant'); None: the shared
    :attr:`EscFilters.plant_frequency_radps`."""
    lowpass_radps: float | None = None
    """This channel's low-pass cut-off after demodulation [rad/s]; None: the shared
    :attr:`EscFilters.lowpass_radps`. (The high-pass acts on the one objective, so it is
    shared; the low-pass acts on each channel's product and may differ: a fast channel can
    average over a shorter time than a slow one.)"""

    def __post_init__(self) -> None:
        if not self.low <= self.initial <= self.high:
            raise ConfigError(f"{self.name}: initial value {self.initial!r} outside "
                              f"[{self.low!r}, {self.high!r}]")


@dataclass(frozen=True)
class EscFilters:
    """The shared filters and the plant's main frequency (for the tuning rules)."""

    highpass_radps: float
    lowpass_radps: float
    plant_frequency_radps: float
    demodulation_ratio_min: float = 10.0
    """``b / a`` below this breaches "demodulation much larger than modulation"."""


@dataclass(frozen=True)
class EscAdaptation:
    """How the objective is scaled and how the step evolves (module docstring)."""

    normalise_by_mean: bool = False
    """Divide the high-passed objective by its running mean."""
    mean_floor: float = 1e-9
    """The running mean is floored at this before dividing by it."""
    step_decay_s: float = math.inf
    """``T``: a channel tuned for ``tau`` seconds steps ``k / (1 + tau / T)`` (inf: constant)."""

    def __post_init__(self) -> None:
        if not self.mean_floor > 0.0:
            raise ConfigError(f"ESC mean floor {self.mean_floor!r}: expected a positive number")
        if not self.step_decay_s > 0.0:
            raise ConfigError(f"ESC step decay {self.step_decay_s!r} s: expected a positive "
                              "number of seconds (inf: no decay)")


def tuning_breaches(channels: tuple[EscChannel, ...], filters: EscFilters,
                    dt_s: float) -> list[str]:
    """Every breached tuning rule, one sentence each naming it (module docstring)."""
    breaches = []
    nyquist = math.pi / dt_s

    def lowpass(c: EscChannel) -> float:
        return c.lowpass_radps if c.lowpass_radps is not None else filters.lowpass_radps

    for c in channels:
        w = c.frequency_radps
        plant_radps = c.plant_frequency_radps if c.plant_frequency_radps is not None \
            else filters.plant_frequency_radps
        if w >= plant_radps:
            breaches.append(f"rule 'perturbation slower than the plant': {c.name} omega = "
                            f"{w:g} rad/s is not below the frequency of the plant's mode it "
                            f"acts through, {plant_radps:.4g} rad/s")
        if filters.highpass_radps >= w:
            breaches.append(f"rule 'high-pass cut-off below the perturbation': omega_h = "
                            f"{filters.highpass_radps:g} rad/s >= {c.name} omega = {w:g} rad/s")
        if lowpass(c) >= w:
            breaches.append(f"rule 'low-pass cut-off below the perturbation': {c.name} "
                            f"omega_l = {lowpass(c):g} rad/s >= omega = {w:g} rad/s")
        if w >= nyquist:
            breaches.append(f"rule 'perturbation below the Nyquist frequency': {c.name} omega = "
                            f"{w:g} rad/s >= pi / dt = {nyquist:g} rad/s")
        if c.demodulation_amplitude < filters.demodulation_ratio_min * c.amplitude:
            breaches.append(
                f"rule 'demodulation amplitude much larger than modulation': {c.name} b = "
                f"{c.demodulation_amplitude:g} < {filters.demodulation_ratio_min:g} x a = "
                f"{filters.demodulation_ratio_min * c.amplitude:g}")
        if c.step <= 0.0:
            breaches.append(f"rule 'positive integrator step': {c.name} k = {c.step:g}")
    tolerance = 1e-9
    for first, second in itertools.combinations(channels, 2):
        spacing = abs(first.frequency_radps - second.frequency_radps)
        if spacing < tolerance:
            breaches.append(f"rule 'distinct perturbation frequencies': {first.name} and "
                            f"{second.name} share omega = {first.frequency_radps:g} rad/s")
        else:
            for c in (first, second):
                if lowpass(c) >= spacing:
                    breaches.append(
                        f"rule 'low-pass cut-off below the frequency spacing': {c.name} "
                        f"omega_l = {lowpass(c):g} rad/s >= |omega_{first.name} - "
                        f"omega_{second.name}| = {spacing:g} rad/s")
        for third in channels:
            if third is first or third is second:
                continue
            if abs(first.frequency_radps + second.frequency_radps
                   - third.frequency_radps) <= max(lowpass(third), tolerance):
                breaches.append(
                    f"rule 'no frequency the sum of two others': {first.name} + {second.name}"
                    f" = {first.frequency_radps + second.frequency_radps:g} rad/s is within "
                    f"the low-pass cut-off of {third.name} omega = "
                    f"{third.frequency_radps:g} rad/s")
    for first, second in itertools.permutations(channels, 2):
        if abs(2.0 * first.frequency_radps - second.frequency_radps) <= max(
                lowpass(second), tolerance):
            breaches.append(
                f"rule 'no frequency twice another': 2 x {first.name} omega = "
                f"{2.0 * first.frequency_radps:g} rad/s is within the low-pass cut-off of "
                f"{second.name} omega = {second.frequency_radps:g} rad/s")
    return breaches


def warn_breaches(channels: tuple[EscChannel, ...], filters: EscFilters, dt_s: float) -> None:
    """Warn (:class:`EscTuningWarning`) once per breached rule."""
    for breach in tuning_breaches(channels, filters, dt_s):
        warnings.warn(f"extremum seeking: {breach}", EscTuningWarning, stacklevel=2)


@dataclass(frozen=True)
class EscStep:
    """One ESC update: the parameters to apply now and the estimate they perturb."""

    t_s: float
    objective: float
    estimate: tuple[float, ...]
    """``theta_hat``: the tuned values without the perturbation."""
    applied: tuple[float, ...]
    """``theta_hat + a sin(omega t)``, clipped to the bounds: what the loop uses now."""
    gradient: tuple[float, ...]
    """``xi``: the demodulated, low-passed objective (``~ a b / 2 dJ/dtheta``)."""


class ExtremumSeeker:
    """Perturbation-based ESC over the parameters ``channels``, updated every ``dt_s``."""

    def __init__(self, channels: tuple[EscChannel, ...], filters: EscFilters,
                 dt_s: float, adaptation: EscAdaptation | None = None) -> None:
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ConfigError(f"ESC update period {dt_s!r}: expected a positive number")
        self.channels = channels
        self.filters = filters
        self.dt_s = dt_s
        self.adaptation = adaptation if adaptation is not None else EscAdaptation()
        self._highpass_decay = math.exp(-filters.highpass_radps * dt_s)
        self._lowpass_decay = tuple(
            math.exp(-(c.lowpass_radps if c.lowpass_radps is not None
                       else filters.lowpass_radps) * dt_s) for c in channels)
        self.reset()

    def reset(self) -> None:
        self._estimate = [c.initial for c in self.channels]
        self._gradient = [0.0] * len(self.channels)
        self._tuned_s = [0.0] * len(self.channels)
        self._objective_mean: float | None = None

    @property
    def estimate(self) -> tuple[float, ...]:
        return tuple(self._estimate)

    def applied(self, t_s: float) -> tuple[float, ...]:
        """The perturbed parameters at ``t_s`` (the estimate plus ``a sin(omega t)``)."""
        return tuple(
            min(max(theta + c.amplitude * math.sin(c.frequency_radps * t_s), c.low), c.high)
            for theta, c in zip(self._estimate, self.channels, strict=True))

    def update(self, t_s: float, objective: float,
               active: tuple[bool, ...] | None = None) -> EscStep:
        """Take the objective measured at ``t_s`` and return the parameters to apply from
        ``t_s`` until the next update.

        ``active`` (one flag per channel, default all) names the parameters the objective
        depends on now: an inactive one is held (its estimate and its filter do not move),
        so it does not wander on the objective's noise while it has no effect on it. While
        none is active the high-pass filter is not fed either, and it restarts from the
        objective when tuning resumes: the mean it removes is that of the regime being
        tuned (a mean carried over from another regime, such as an approach whose
        objective falls by orders of magnitude, would enter as a slow transient that the
        demodulation reads as a gradient).
        """
        if not math.isfinite(objective):
            return EscStep(t_s, objective, self.estimate, self.applied(t_s),
                           tuple(self._gradient))
        if active is not None and not any(active):
            self._objective_mean = None
            return EscStep(t_s, objective, self.estimate, self.applied(t_s),
                           tuple(self._gradient))
        if self._objective_mean is None:
            self._objective_mean = objective  # start the high-pass without a transient
        mean = self._objective_mean
        mean = objective + (mean - objective) * self._highpass_decay
        self._objective_mean = mean
        adaptation = self.adaptation
        highpassed = objective - mean
        if adaptation.normalise_by_mean:
            highpassed /= max(mean, adaptation.mean_floor)
        for i, c in enumerate(self.channels):
            if active is not None and not active[i]:
                continue
            demodulated = highpassed * c.demodulation_amplitude * math.sin(
                c.frequency_radps * t_s)
            gradient = demodulated + (self._gradient[i] - demodulated) * self._lowpass_decay[i]
            self._gradient[i] = gradient
            step = c.step / (1.0 + self._tuned_s[i] / adaptation.step_decay_s)
            self._tuned_s[i] += self.dt_s
            theta = self._estimate[i] - step * gradient * self.dt_s
            self._estimate[i] = min(max(theta, c.low), c.high)
        return EscStep(t_s, objective, self.estimate, self.applied(t_s),
                       tuple(self._gradient))
