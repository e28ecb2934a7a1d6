"""Adaptive cruise control: a proportional law on speed, gap and relative speed, its three
gains tuned online by extremum seeking; the steering stays an existing path tracker's.

From the latest range reading (:class:`cosim.core.traffic_records.RangeReading`: gap ``d`` to
the target's rear, range rate ``v_rel``) and the estimated forward speed ``v``:

    speed law:  a_v = K_v (v_set - v)
    gap law:    a_x = K_x (d - d_des) + K_vrel v_rel,   d_des = d0 + h v

``d_des`` is the constant-time-gap spacing policy (Rajamani, "Vehicle Dynamics and Control",
Springer 2012, ch. 6). The ACC is in *speed mode* while the gap is safe for cruising, i.e.
no target or the gap law allows at least what the speed law asks (``a_x >= a_v``), and in
*gap mode* otherwise; the command is the active law's, so the car never exceeds the set
speed behind a faster target. The command is then limited in jerk and acceleration
(``tracker.acc``: ISO 15622 comfort limits by default). A target lost from the readings
(a dropout) is extrapolated with its last range rate for ``range_timeout_s``.

The objective extremum seeking minimises, evaluated every control step from what the
controller knows (its readings, its estimate, its own commands):

    J = w_x e_x^2 + w_v e_v^2 + w_j ((a_k - a_{k-1}) / dt)^2

with ``e_x = d - d_des`` and ``e_v = v_rel`` (the target's speed minus the ego's) in gap
mode, ``e_x = 0`` and ``e_v = v_set - v`` in speed mode: gap error, speed error and change
of acceleration. The gains ``(K_v, K_x, K_vrel)`` are the ESC's parameters
(:class:`tracker.cruise.esc.ExtremumSeeker`, ``tracker.acc.esc``); only the active law's gains
are tuned (``K_v`` in speed mode, ``K_x`` and ``K_vrel`` in gap mode: the objective does
not depend on the others then), and only in a steady regime (``esc.max_gap_error_m``,
``esc.max_speed_error_mps``): averaging, which ESC rests on (Krstic and Wang 2000), needs
the objective to vary through the perturbation, and a transient such as the approach from
400 m, whose objective falls by orders of magnitude, would be read as a gradient and drive
the gains to their bounds. With ``esc.enabled: false`` they stay at
``tracker.acc.k_*``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosim.core.records import Command, Estimate, Plan
from cosim.core.traffic_records import RangeReading
from tracker.cruise.config import GAIN_NAMES, AccConfig, EscGainConfig
from tracker.cruise.esc import EscAdaptation, EscChannel, EscFilters, ExtremumSeeker, warn_breaches
from tracker.paths.reference_path import ReferencePath
from tracker.protocol import Closable, Resettable, Tracker


@dataclass(frozen=True)
class AccStatus:
    """What the ACC did at one control step (logged on ``/acc/*``)."""

    t_s: float
    mode: str
    target: str
    gap_m: float
    range_rate_mps: float
    desired_gap_m: float
    speed_mps: float
    accel_mps2: float
    objective: float
    gains: tuple[float, float, float]
    """The gains applied at this step (ESC's estimate plus its perturbation)."""
    gain_estimates: tuple[float, float, float]
    """ESC's estimate of the best gains (without perturbation)."""

    def gains_message(self) -> dict[str, float]:
        return {"t_s": self.t_s,
                **{name: value for name, value in zip(GAIN_NAMES, self.gains, strict=True)},
                **{f"{name}_estimate": value
                   for name, value in zip(GAIN_NAMES, self.gain_estimates, strict=True)}}


def loop_modes_radps(k_v: float, k_x: float, k_vrel: float,
                     time_gap_s: float) -> tuple[float, float, float]:
    """The frequency of the loop mode each gain acts through, in :data:`GAIN_NAMES` order
    [rad/s], on the ACC's design model: a point mass ``dv/dt = a`` (actuator lag and delays,
    a few tenths of a second, are fast beside these modes).

    Speed mode: ``dv/dt = K_v (v_set - v)``, one pole at ``K_v``. Gap mode: with ``dd/dt =
    v_lead - v`` and the gap law, the characteristic polynomial is ``s^2 + (K_vrel + h K_x)
    s + K_x``. With ``K_x`` small its roots split into a fast one near ``K_vrel + h K_x``
    (set by ``K_vrel``: the relative speed decays) and a slow one near ``K_x / (K_vrel + h
    K_x)`` (set by ``K_x``: the gap creeps back to the desired gap), so ``K_vrel`` acts
    through the fast mode and ``K_x`` through the slow one. Complex roots (``K_x`` large):
    both at the natural frequency ``sqrt(K_x)``.
    """
    damping = k_vrel + time_gap_s * k_x
    discriminant = damping * damping - 4.0 * k_x
    if discriminant < 0.0:
        natural = math.sqrt(k_x)
        return k_v, natural, natural
    root = math.sqrt(discriminant)
    return k_v, 0.5 * (damping - root), 0.5 * (damping + root)


def _channel(name: str, initial: float, gain: EscGainConfig,
             plant_frequency_radps: float) -> EscChannel:
    return EscChannel(name=name, initial=initial, low=gain.low, high=gain.high,
                      amplitude=gain.amplitude, frequency_radps=gain.frequency_radps,
                      demodulation_amplitude=gain.demodulation_amplitude, step=gain.step,
                      plant_frequency_radps=plant_frequency_radps,
                      lowpass_radps=gain.lowpass_radps if gain.lowpass_radps > 0.0 else None)


class AccTracker:
    """The ACC around a path tracker ``lateral`` (module docstring)."""

    def __init__(self, lateral: Tracker, config: AccConfig, period_s: float) -> None:
        self.lateral = lateral
        self.config = config
        self.period_s = period_s
        esc = config.esc
        modes = loop_modes_radps(config.k_v, config.k_x, config.k_vrel, config.time_gap_s) \
            if esc.plant_frequency_radps == 0.0 else (esc.plant_frequency_radps,) * 3
        self._channels = tuple(
            _channel(name, getattr(config, name), getattr(esc, name), mode)
            for name, mode in zip(GAIN_NAMES, modes, strict=True))
        filters = EscFilters(esc.highpass_radps, esc.lowpass_radps, esc.plant_frequency_radps,
                             esc.demodulation_ratio_min)
        adaptation = EscAdaptation(
            normalise_by_mean=esc.normalise_by_mean, mean_floor=esc.objective_floor,
            step_decay_s=esc.step_decay_s if esc.step_decay_s > 0.0 else math.inf)
        self.seeker: ExtremumSeeker | None = None
        if esc.enabled:
            warn_breaches(self._channels, filters, period_s)
            self.seeker = ExtremumSeeker(self._channels, filters, period_s, adaptation)
        self.reset()

    def reset(self) -> None:
        if isinstance(self.lateral, Resettable):
            self.lateral.reset()
        if self.seeker is not None:
            self.seeker.reset()
        self._reading: RangeReading | None = None
        self._accel_mps2 = 0.0
        self._accel_before_mps2 = 0.0
        self._last_t_s: float | None = None
        self.status: AccStatus | None = None
        """The last step's status (None before the first step)."""

    def close(self) -> None:
        """Release what the path tracker holds (:class:`tracker.protocol.Closable`)."""
        if isinstance(self.lateral, Closable):
            self.lateral.close()

    def observe_range(self, reading: RangeReading) -> None:
        """A range reading arrived (the runner delivers each one the sensor samples)."""
        self._reading = reading

    def _target(self, t_s: float) -> tuple[str, float, float]:
        """(target, gap now, range rate) from the latest reading, extrapolated over its age."""
        reading = self._reading
        if reading is None or not reading.has_target:
            return "", math.nan, math.nan
        age_s = t_s - reading.t_s
        if age_s > self.config.range_timeout_s:
            return "", math.nan, math.nan
        return reading.target, reading.gap_m + reading.range_rate_mps * age_s, \
            reading.range_rate_mps

    def _tuned(self, previous: AccStatus | None, gap_error_m: float,
               speed_error_mps: float) -> tuple[bool, bool, bool]:
        """Which gains ESC tunes now: the active law's, in a steady regime only."""
        esc = self.config.esc
        if previous is not None and previous.mode == "gap":
            steady = abs(gap_error_m) < esc.max_gap_error_m
            return False, steady, steady
        return abs(speed_error_mps) < esc.max_speed_error_mps, False, False

    def step(self, t_s: float, estimate: Estimate,
             reference: ReferencePath) -> tuple[Command, Plan]:
        command, plan = self.lateral.step(t_s, estimate, reference)
        c = self.config
        dt = self.period_s if self._last_t_s is None or t_s <= self._last_t_s \
            else t_s - self._last_t_s
        speed = estimate["vx_mps"]
        target, gap, range_rate = self._target(t_s)
        desired_gap = c.standstill_gap_m + c.time_gap_s * max(speed, 0.0)
        # The objective of the interval that just ended, measured now (module docstring).
        previous = self.status
        if previous is not None and previous.mode == "gap" and target:
            objective = (c.weight_gap * (gap - desired_gap) ** 2
                         + c.weight_speed * range_rate ** 2)
        else:
            objective = c.weight_speed * (c.set_speed_mps - speed) ** 2
        if previous is not None:
            jerk = (previous.accel_mps2 - self._accel_before_mps2) / dt
            objective += c.weight_jerk * jerk ** 2
        if self.seeker is not None:
            if math.isfinite(speed):
                esc = c.esc
                seek_on = math.log(objective + esc.objective_floor) if esc.log_objective \
                    else objective
                gains = self.seeker.update(t_s, seek_on, self._tuned(
                    previous, gap - desired_gap, c.set_speed_mps - speed)).applied
            else:
                gains = self.seeker.applied(t_s)
            estimates = self.seeker.estimate
        else:
            gains = estimates = (c.k_v, c.k_x, c.k_vrel)
        k_v, k_x, k_vrel = gains
        accel_speed = k_v * (c.set_speed_mps - speed)
        mode, demand = "speed", accel_speed
        if target:
            accel_gap = k_x * (gap - desired_gap) + k_vrel * range_rate
            if accel_gap < accel_speed:
                mode, demand = "gap", accel_gap
        if not math.isfinite(demand):
            demand = c.accel_min_mps2  # no speed estimate: brake (a safe stop)
        step_max = c.jerk_max_mps3 * dt
        accel = min(max(demand, self._accel_mps2 - step_max), self._accel_mps2 + step_max)
        accel = min(max(accel, c.accel_min_mps2), c.accel_max_mps2)
        self._accel_before_mps2 = self._accel_mps2
        self._accel_mps2 = accel
        self._last_t_s = t_s
        self.status = AccStatus(
            t_s=t_s, mode=mode, target=target, gap_m=gap, range_rate_mps=range_rate,
            desired_gap_m=desired_gap, speed_mps=speed, accel_mps2=accel,
            objective=objective, gains=(k_v, k_x, k_vrel),
            gain_estimates=tuple(estimates))  # type: ignore[arg-type]
        return Command(t_s=command.t_s, accel_mps2=accel, steer_rad=command.steer_rad), plan
