"""A filter whose belief about a sensor disagrees with the sensor: said at the end of a run.

The sensors' true noise (``sensors.*``) and what the filter believes about it
(``estimator.noise.*``) are separate data, so ``--set sensors.gnss.sigma_m=0.1`` alone
makes a receiver worse than the filter thinks. The filter then tracks on regardless, and
the run can end ``ok``; what shows it is the sensor's normalised innovation squared per
degree of freedom (``nis_<sensor>``, :mod:`cosim.simulation.metrics`), about 1 for a
consistent filter. Outside ``[NIS_LOW, NIS_HIGH]`` over a run the belief is wrong by more
than the test's spread can explain (Bar-Shalom, Li, Kirubarajan, "Estimation with
Applications to Tracking and Navigation", Wiley 2001, section 5.4: the chi-square band
of a mean over hundreds of degrees of freedom is a few tenths wide): one line names the
sensor, its NIS and both sigmas, and the runner writes it on ``/events`` (kind
``belief_mismatch``; not an outcome event: the run's outcome does not change). It is said
only when a sensor figure and its belief differ: with equal figures an out-of-band NIS
(a short run's start, a model error) is the filter's own matter, in ``nis_<sensor>``; a
noise-free sensor (the ``ideal`` suite, for debugging) cannot be believed exactly, so the
filter is under-confident there by design.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from cosim.core.sensor_names import GNSS, GNSS_VELOCITY, HEADING, IMU, STEERING, WHEEL_SPEED

NIS_LOW = 0.3
NIS_HIGH = 3.0
"""The band of NIS per degree of freedom within which a sensor's belief passes."""

MIN_DOF = 20
"""Fewer summed degrees of freedom than this say too little to warn about."""

SIGMA_KEYS: dict[str, tuple[tuple[str, str], ...]] = {
    GNSS: (("sensors.gnss.sigma_m", "estimator.noise.gnss_sigma_m"),),
    GNSS_VELOCITY: (("sensors.gnss_velocity.sigma_mps",
                     "estimator.noise.gnss_velocity_sigma_mps"),),
    HEADING: (("sensors.heading.sigma_rad", "estimator.noise.heading_sigma_rad"),),
    IMU: (("sensors.imu.gyro_sigma_radps", "estimator.noise.gyro_sigma_radps"),
          ("sensors.imu.accel_sigma_mps2", "estimator.noise.accel_sigma_mps2")),
    WHEEL_SPEED: (("sensors.wheel_speed.sigma_radps", "estimator.noise.wheel_sigma_radps"),),
    STEERING: (("sensors.steering.sigma_rad", "estimator.noise.steer_sigma_rad"),),
}
"""Per fused sensor, its noise keys: (the sensor's truth, the filter's belief)."""


class BeliefMismatchWarning(UserWarning):
    """The filter's belief about a sensor disagrees with what the sensor delivers."""


@dataclass(frozen=True)
class BeliefMismatch:
    """One sensor whose NIS per degree of freedom left the band."""

    sensor: str
    nis: float
    bound: float
    """The bound it crossed (:data:`NIS_LOW` or :data:`NIS_HIGH`)."""
    line: str


def _value(config: dict[str, Any], dotted: str) -> Any:
    node: Any = config
    for part in dotted.split("."):
        node = node.get(part) if isinstance(node, dict) else None
    return node


def belief_mismatches(metrics: dict[str, Any], config: dict[str, Any]) -> list[BeliefMismatch]:
    """The sensors of ``metrics`` whose ``nis_<sensor>`` left the band, with a line naming
    both sigmas from ``config`` (the run's configuration as plain dictionaries)."""
    found = []
    for sensor, keys in SIGMA_KEYS.items():
        nis, dof = metrics.get(f"nis_{sensor}"), metrics.get(f"nis_dof_{sensor}", 0)
        if nis is None or dof < MIN_DOF or NIS_LOW <= nis <= NIS_HIGH:
            continue
        if all(_value(config, truth) == _value(config, belief) for truth, belief in keys):
            continue  # the figures agree: the filter's model, not the configuration
        if all(_value(config, truth) == 0.0 for truth, _ in keys):
            continue  # a noise-free sensor (the ideal suite): no filter can believe it
        bound = NIS_HIGH if nis > NIS_HIGH else NIS_LOW
        sigmas = "; ".join(f"{truth} = {_value(config, truth):g}, the filter believes "
                           f"{belief} = {_value(config, belief):g}" for truth, belief in keys)
        found.append(BeliefMismatch(
            sensor, float(nis), bound,
            f"{sensor} NIS per dof {nis:.3g} over the run, outside [{NIS_LOW:g}, "
            f"{NIS_HIGH:g}]: the filter's belief disagrees with the sensor ({sigmas}); set "
            "both to the same figure unless the mismatch is the study"))
    return found
