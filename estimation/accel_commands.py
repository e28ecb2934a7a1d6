"""The acceleration commands a filter has been told: the drive's response as a known input.

The controller asks for a longitudinal acceleration ``a_c`` (:class:`cosim.core.records.Command`);
the low-level layer (:mod:`cosim.plant.low_level`) turns it into drive or brake torque
through the belief of the car's mass and road loads, so the car's acceleration changes
with the command, within a few milliseconds of it reaching the actuator. A filter whose
acceleration state is a random walk learns of that change only from the accelerometer,
after it happened: at a launch the command steps by 1 m/s^2 within one 10 ms IMU interval
against a predicted spread of a few cm/s^2, the IMU's NIS is in the hundreds, and the
covariance room made for that surprise lets the wheel speeds and the steering be gated
for the rest of the first second.

Told the commands, the filter moves its acceleration with them. The drive is believed to
follow its command through a first-order lag of time constant ``tau`` (the drive's own
response, tyre slip build-up included), from the level ``L_i`` the lag had when command
``i`` started at ``t_i``::

    a_lag(t) = a_i + (L_i - a_i) exp(-(t - t_i) / tau),    t_i <= t < t_{i+1}     (A1)

and the acceleration state moves by the lag's change over each prediction sub-step,
``x_a(t1) = x_a(t0) + a_lag(t1) - a_lag(t0)`` (plus its own process noise): an input, so
what the filter learned of the difference between the car's acceleration and its command
(a wrong belief of the mass or the drag, a grade) is kept, not pulled back to the command.
The car follows a change of its command with a gain the belief gets wrong (the mass, the
tyres' transient): a relative error ``epsilon_i ~ N(0, sigma^2)`` per command, the same over
the command's lag, so the variance of the acceleration grows by::

    V_i(t) = sigma^2 (a_lag(t) - L_i)^2                                              (A2)

over command ``i`` (added in increments as the lag progresses, whatever the sub-steps).
Before the first command the drive holds the acceleration the filter believes (the lag is
at 0 and does not move).

What a command ``a_c`` gives in a turn is less: the low-level layer's model of the road
loads holds no cornering drag, the front tyres' lateral force along the car ``-F_yf
sin(delta) / m`` (on the MuJoCo sedan ``a_x - a_c`` is 0.94 times it, with 0.014 m/s^2 RMS
left; it was 0.16 m/s^2 RMS on the circuit). The filter therefore adds the drag, evaluated
at its estimate when it is told the command, to the level ``a_i`` it is told
(:meth:`estimation.fusion.KalmanFusion.accel_command`): the level stays an input, a number
fixed per command, so the prediction does not depend on how an interval is split, and the
UKF's sigma points all move by the same amount.

Like the steering commands the commands are inputs, not the filter's state
(:mod:`estimation.command_timeline`): a re-run after a late measurement
(:mod:`estimation.history`) meets them again; the lag (A1) is a function of time and the
commands only.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from estimation.command_timeline import CommandTimeline


@dataclass(frozen=True)
class DriveBelief:
    """The numbers of (A1)-(A2)."""

    time_constant_s: float
    """``tau``: how fast the car's acceleration follows its command [s]."""
    relative_sigma: float
    """``sigma``: the standard deviation of the fraction of a command's change the car
    does not follow."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.time_constant_s) and self.time_constant_s > 0.0):
            raise ValueError(f"time_constant_s = {self.time_constant_s!r}: expected > 0")
        if not (math.isfinite(self.relative_sigma) and self.relative_sigma >= 0.0):
            raise ValueError(f"relative_sigma = {self.relative_sigma!r}: expected >= 0")


class AccelCommands(CommandTimeline):
    """A timeline of acceleration commands and the drive's lag behind them (module
    docstring)."""

    what = "acceleration command"
    unit = " m/s^2"

    def __init__(self, belief: DriveBelief) -> None:
        super().__init__()
        self.belief = belief
        self._start_levels_mps2: list[float] = []
        """``L_i`` of (A1): the lag's level when each command started."""

    def clear(self) -> None:
        super().clear()
        self._start_levels_mps2.clear()

    def _appending(self, t_s: float) -> None:
        self._start_levels_mps2.append(self.level(t_s))

    def _dropped(self, count: int) -> None:
        del self._start_levels_mps2[:count]

    def level(self, t_s: float) -> float:
        """``a_lag(t_s)`` of (A1): 0 before the first command."""
        i = bisect.bisect_right(self._times_s, t_s) - 1
        return self._level_of(i, t_s) if i >= 0 else 0.0

    def _level_of(self, i: int, t_s: float) -> float:
        """(A1) under command ``i`` at ``t_s`` (within its time)."""
        command = self._values[i]
        elapsed_s = max(t_s - self._times_s[i], 0.0)
        return command + (self._start_levels_mps2[i] - command) * math.exp(
            -elapsed_s / self.belief.time_constant_s)

    def _variance_of(self, i: int, t_s: float) -> float:
        """(A2) under command ``i`` at ``t_s``."""
        return self._variance_at_level(i, self._level_of(i, t_s))

    def _variance_at_level(self, i: int, level_mps2: float) -> float:
        """(A2) under command ``i`` where (A1) is at ``level_mps2``."""
        progress = level_mps2 - self._start_levels_mps2[i]
        return (self.belief.relative_sigma * progress) ** 2

    def increment(self, t0_s: float, t1_s: float) -> tuple[float, float]:
        """``(a_lag(t1) - a_lag(t0), the variance (A2) added over (t0, t1])``: what a
        prediction from ``t0_s`` to ``t1_s`` adds to the acceleration's mean and variance
        ((0, 0) before the first command and with no command since)."""
        times = self._times_s
        if not times or t1_s <= times[0]:
            return 0.0, 0.0
        i = bisect.bisect_right(times, t0_s) - 1
        last = bisect.bisect_right(times, t1_s) - 1
        if i < 0:  # the first command starts inside: the lag is at 0 until then
            i, t0_s = 0, times[0]
        start_level = self._level_of(i, t0_s)  # each level once: the same numbers
        variance = -self._variance_at_level(i, start_level)
        while i < last:  # each command that ends inside, to its end
            variance += self._variance_of(i, times[i + 1])
            i += 1
        end_level = self._level_of(last, t1_s)
        variance += self._variance_at_level(last, end_level)
        return end_level - start_level, variance

    def moved(self, mean: np.ndarray, covariance: np.ndarray, index: int, t0_s: float,
              t1_s: float) -> tuple[np.ndarray, np.ndarray] | None:
        """``mean`` and ``covariance`` (new arrays) with the acceleration, state ``index``,
        moved by :meth:`increment` over ``(t0_s, t1_s]``; None where nothing moves."""
        mean_mps2, variance = self.increment(t0_s, t1_s)
        if not (mean_mps2 or variance):
            return None
        mean, covariance = mean.copy(), covariance.copy()
        mean[index] += mean_mps2
        covariance[index, index] += variance
        return mean, covariance
