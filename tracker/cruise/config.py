"""Configuration of adaptive cruise control: ``tracker.acc`` (and its ESC, ``tracker.acc.esc``).

Defaults: a 1.8 s time gap and 5 m at standstill (the constant-time-gap policy, Rajamani,
"Vehicle Dynamics and Control", Springer 2012, ch. 6); acceleration between -3.5 and
2 m/s^2 and jerk within 2.5 m/s^3, the comfort limits ISO 15622:2018 ("Adaptive cruise
control systems") sets for an ACC (harder braking is the driver's, or an emergency brake's).
The minimum safe gap is ``safe_standstill_gap_m + safe_time_gap_s v`` (2 m and 1 s: half
the usual recommendation of two seconds); the metrics judge a run against it.

The ESC defaults are slow because the loop they tune is (docs/acc.md has the measurements
behind each choice). The gap-keeping loop has two modes
(:func:`tracker.cruise.law.loop_modes_radps`): a fast one, about ``K_vrel``, through which
``K_vrel`` acts, and a slow one, about ``K_x / K_vrel`` (0.077 rad/s at the ``acc``
scenario's initial gains), through which ``K_x`` acts; and the lead car's harmonic speed
puts a strong component into the objective at twice its own frequency (0.63 rad/s for a 20 s
period). So ``K_vrel`` is perturbed at 0.17 rad/s and ``K_x`` at 0.035 rad/s, below the slow
mode (perturbed at 0.13 rad/s, the objective's response to ``K_x`` lagged by more than 90
degrees and ESC raised ``K_x`` where the objective wanted it lower); ``K_v`` at 0.1 rad/s;
the high-pass at 0.01 and the low-pass at 0.015 rad/s, below every perturbation and spacing.
The objective is normalised by its running mean (``normalise_by_mean``: a relative gradient
whose minimiser is that of the mean objective) and the step decays as ``1 / (1 + tau /
step_decay_s)`` (the stochastic approximation schedule: with a constant step the noisy
gradient keeps the gains wandering by several per cent). Tuning runs only in a steady regime
(``max_gap_error_m``, ``max_speed_error_mps``). The rules are checked when the ACC starts
(:mod:`tracker.cruise.esc`), each gain's perturbation against the frequency of its own loop
mode at the initial gains.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from cosim.core.config_fields import section, setting
from cosim.core.exceptions import ConfigError

GAIN_NAMES = ("k_v", "k_x", "k_vrel")
"""The tuned gains, in the ESC's parameter order."""


@dataclass(frozen=True)
class EscGainConfig:
    """Extremum seeking on one gain: bounds, perturbation, demodulation, step."""

    low: float = setting(0.01, low=0.0, high=100.0, doc="smallest value ESC may set")
    high: float = setting(3.0, low=0.0, high=100.0, doc="largest value ESC may set")
    amplitude: float = setting(0.02, low=0.0, high=100.0, doc="modulation amplitude a")
    frequency_radps: float = setting(0.5, low=1e-4, high=1e3, doc="perturbation omega")
    demodulation_amplitude: float = setting(1.0, low=0.0, high=1e6, doc="demodulation b")
    step: float = setting(0.05, low=-1e6, high=1e6, doc="integrator gain k")
    lowpass_radps: float = setting(
        0.0, low=0.0, high=1e3, doc="this gain's low-pass cut-off (0: esc.lowpass_radps)")


def _gain_config(gain: str, **defaults: float) -> type:
    """An :class:`EscGainConfig` with this gain's defaults (so that setting one key of
    ``tracker.acc.esc.<gain>`` keeps the others at this gain's defaults, not the base's)."""
    fields = []
    for field in dataclasses.fields(EscGainConfig):
        meta = field.metadata
        default = defaults.get(field.name, field.default)
        fields.append((field.name, float, setting(default, low=meta["low"],
                                                  high=meta["high"], doc=meta["doc"])))
    cls = dataclasses.make_dataclass(f"Esc_{gain}_Config", fields, bases=(EscGainConfig,),
                                     frozen=True, namespace={"__module__": __name__})
    cls.__doc__ = f"ESC on ``{gain}``."
    return cls


EscKvConfig = _gain_config("k_v", high=2.0, amplitude=0.02, frequency_radps=0.25, step=0.01)
EscKxConfig = _gain_config("k_x", high=1.0, amplitude=0.01, frequency_radps=0.035,
                           step=0.002)
EscKvrelConfig = _gain_config("k_vrel", high=3.0, amplitude=0.05, frequency_radps=0.17,
                              step=0.04, lowpass_radps=0.05)


@dataclass(frozen=True)
class EscConfig:
    """Extremum seeking control tuning the ACC's gains online (:mod:`tracker.cruise.esc`)."""

    enabled: bool = setting(True, doc="false: the gains stay at their initial values")
    highpass_radps: float = setting(0.01, low=0.0, high=1e3, doc="high-pass cut-off omega_h")
    lowpass_radps: float = setting(0.015, low=0.0, high=1e3, doc="low-pass cut-off omega_l")
    plant_frequency_radps: float = setting(
        0.0, low=0.0, high=1e4,
        doc="the plant frequency of the tuning rule 'perturbation slower than the plant', for"
        " every gain; 0: each gain's own loop mode at the initial gains (tracker.acc."
        "loop_modes_radps: K_v; the slow gap mode for k_x, the fast one for k_vrel)")
    demodulation_ratio_min: float = setting(
        10.0, low=1.0, high=1e6, doc="tuning rule: b at least this times a")
    log_objective: bool = setting(
        False, doc="seek on log(J + objective_floor) sample by sample: a gradient relative to "
        "J, but the minimum of E[log J], not of E[J] (normalise_by_mean is the alternative)")
    normalise_by_mean: bool = setting(
        True, doc="divide the high-passed J by its running mean (floored at objective_floor):"
        " a gradient relative to J, so one step suits objectives of 0.1 and of 1000, and the "
        "minimum of E[J]")
    objective_floor: float = setting(
        0.01, low=1e-9, high=1e6, doc="see log_objective and normalise_by_mean")
    step_decay_s: float = setting(
        60.0, low=0.0, high=1e9,
        doc="T: a gain tuned for tau seconds steps k / (1 + tau / T), the stochastic "
        "approximation schedule that lets a noisy ESC settle (0: a constant step)")
    max_gap_error_m: float = setting(
        4.0, low=0.0, high=1e4,
        doc="tune the gap gains only while |gap - desired gap| is below this (a steady regime)")
    max_speed_error_mps: float = setting(
        2.0, low=0.0, high=100.0,
        doc="tune k_v only while |set speed - speed| is below this (a steady regime)")
    settle_window_s: float = setting(
        60.0, low=0.0, high=1e6,
        doc="the gains are judged settled when none moved more than settle_tolerance_pct "
        "over the run's last settle_window_s (metric esc_gain_drift_pct)")
    settle_tolerance_pct: float = setting(
        2.0, low=0.0, high=1e3, doc="see settle_window_s (metric esc_gains_settled)")
    k_v: EscKvConfig = section(EscKvConfig)
    k_x: EscKxConfig = section(EscKxConfig)
    k_vrel: EscKvrelConfig = section(EscKvrelConfig)

    def __post_init__(self) -> None:
        if self.log_objective and self.normalise_by_mean:
            raise ConfigError("tracker.acc.esc.log_objective = true and normalise_by_mean = "
                              "true: expected at most one of them")


@dataclass(frozen=True)
class AccConfig:
    """Adaptive cruise control (:mod:`tracker.cruise.law`): the longitudinal command from the range
    sensor; the steering stays the chosen tracker's (``tracker.name``)."""

    enabled: bool = setting(False, doc="the ACC sets the acceleration (needs traffic)")
    set_speed_mps: float = setting(30.0, low=0.0, high=80.0, doc="cruise speed (108 km/h)")
    time_gap_s: float = setting(1.8, low=0.0, high=10.0, doc="desired time gap h")
    standstill_gap_m: float = setting(5.0, low=0.0, high=100.0, doc="desired gap at rest d0")
    safe_time_gap_s: float = setting(
        1.0, low=0.0, high=10.0,
        doc="minimum safe gap = safe_standstill_gap_m + this x speed (metrics)")
    safe_standstill_gap_m: float = setting(
        2.0, low=0.0, high=100.0, doc="minimum safe gap at rest (metrics)")
    k_v: float = setting(0.4, low=0.0, high=100.0, doc="initial speed-error gain [1/s]")
    k_x: float = setting(0.1, low=0.0, high=100.0, doc="initial gap-error gain [1/s^2]")
    k_vrel: float = setting(0.6, low=0.0, high=100.0, doc="initial relative-speed gain [1/s]")
    accel_min_mps2: float = setting(-3.5, low=-20.0, high=0.0, doc="strongest braking")
    accel_max_mps2: float = setting(2.0, low=0.0, high=20.0, doc="strongest acceleration")
    jerk_max_mps3: float = setting(2.5, low=0.01, high=1e3, doc="|d accel / dt| limit")
    range_timeout_s: float = setting(
        0.5, low=0.0, high=100.0,
        doc="a target unseen this long is dropped (its gap extrapolated until then)")
    weight_gap: float = setting(1.0, low=0.0, high=1e6, doc="objective: gap error^2 [1/m^2]")
    weight_speed: float = setting(1.0, low=0.0, high=1e6,
                                  doc="objective: speed error^2 [s^2/m^2]")
    weight_jerk: float = setting(1.0, low=0.0, high=1e6,
                                 doc="objective: (change of acceleration / dt)^2 [s^6/m^2]")
    esc: EscConfig = section(EscConfig)

    def __post_init__(self) -> None:
        if not self.esc.enabled:
            return
        for gain in ("k_v", "k_x", "k_vrel"):
            bounds = getattr(self.esc, gain)
            value = getattr(self, gain)
            if not bounds.low <= value <= bounds.high:
                raise ConfigError(f"{gain} = {value:g}: expected within esc.{gain}.low = "
                                  f"{bounds.low:g} and esc.{gain}.high = {bounds.high:g}")
