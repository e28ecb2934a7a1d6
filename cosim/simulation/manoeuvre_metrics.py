"""Metrics of the open-loop manoeuvres (ISO 4138 steady circle, ISO 7401 step steer).

Steady state is the mean over the final ``manoeuvre.steady_window_s`` of the run. For the
step steer, ISO 7401's yaw-rate response time runs from the instant the steering input
reaches 50 % of its final value to the instant the yaw rate first reaches 90 % of its steady
value; overshoot is the peak yaw rate over the steady value, minus one. For the ramp steer,
``ay_max_mps2`` is the largest lateral acceleration after a 0.5 s moving average (the tyres'
stick-slip near the limit adds high-frequency content that is not grip).
"""

from __future__ import annotations

import numpy as np

from tracker.manoeuvre import ManoeuvreConfig


def manoeuvre_metrics(t_s: np.ndarray, steer_rad: np.ndarray, yaw_rate_radps: np.ndarray,
                     ay_mps2: np.ndarray, speed_mps: np.ndarray,
                     manoeuvre: ManoeuvreConfig) -> dict[str, float]:
    """Steady-state and (for ``step-steer``) transient figures from the true signals."""
    if t_s.size == 0:
        return {}
    window = t_s >= t_s[-1] - manoeuvre.steady_window_s
    yaw_rate = float(np.mean(yaw_rate_radps[window]))
    steer = float(np.mean(steer_rad[window]))
    speed = float(np.mean(speed_mps[window]))
    metrics = {
        "steady_speed_mps": speed,
        "steady_steer_rad": steer,
        "steady_yaw_rate_radps": yaw_rate,
        "steady_ay_mps2": float(np.mean(ay_mps2[window])),
        "steady_radius_m": speed / yaw_rate if yaw_rate != 0.0 else float("inf"),
        "steady_yaw_rate_gain_1ps": yaw_rate / steer if steer != 0.0 else float("nan"),
    }
    if manoeuvre.kind == "step-steer" and yaw_rate != 0.0 and manoeuvre.steer_rad != 0.0:
        half_steer = np.nonzero(np.abs(steer_rad) >= 0.5 * abs(manoeuvre.steer_rad))[0]
        ninety = np.nonzero(yaw_rate_radps / yaw_rate >= 0.9)[0]
        if half_steer.size and ninety.size:
            metrics["yaw_rate_response_time_s"] = float(t_s[ninety[0]] - t_s[half_steer[0]])
        metrics["yaw_rate_overshoot"] = float(np.max(yaw_rate_radps / yaw_rate) - 1.0)
    if manoeuvre.kind == "ramp-steer" and t_s.size > 1:
        samples = max(1, round(0.5 / float(np.median(np.diff(t_s)))))
        smoothed = np.convolve(ay_mps2, np.ones(samples) / samples, mode="valid")
        metrics["ay_max_mps2"] = float(np.max(np.abs(smoothed)))
    return metrics
