"""The order in which a filter fuses one instant's measurements one after another.

Linear updates commute: fused one after another they give the joint update's posterior in
any order. A nonlinear one does not: it is linearised (the EKF) or its sigma points are
drawn (the UKF) at the belief the updates before it left. Fused first, the sensors that
measure states themselves (the steering angle, the GNSS position, the heading) narrow the
states the others' models depend on. At a run's first instant, the prior's road-wheel angle
drawn a few degrees off, the IMU's lateral acceleration went through the bicycle's
saturated tyres before the steering sensor had spoken, and the steering was gated for the
next tenth of a second.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from cosim.core.records import Measurement
from estimation.measurement_models import MeasurementModel


def linear_first(measurements: Sequence[Measurement],
                 models: Mapping[str, MeasurementModel]) -> list[int]:
    """The indices of ``measurements``: those whose sensor's model is linear in the state
    (:attr:`estimation.measurement_models.MeasurementModel.linear`) first, then the others,
    each group in the order given (a sensor without a model counts as nonlinear)."""
    rank = [0 if (model := models.get(m.sensor)) is not None and model.linear else 1
            for m in measurements]
    return sorted(range(len(measurements)), key=rank.__getitem__)
