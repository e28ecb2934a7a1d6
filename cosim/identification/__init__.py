"""System identification of the MuJoCo plant in the controllers' model families.

The plant is driven directly through scripted manoeuvres (:mod:`.manoeuvres`); pure fits
(:mod:`.fits`) turn the measurements into the kinematic bicycle's effective wheelbase, the
linear-tyre dynamic bicycle's axle cornering stiffnesses and understeer gradient
(Rajamani, "Vehicle Dynamics and Control", 2nd ed., Springer 2012, sec. 2.3 and 3.5;
:mod:`tracker.models.dynamic_bicycle`), and the steering and longitudinal
actuator lags; :func:`identify` runs it all (:mod:`.procedure`) and returns an
:class:`IdentifiedModel`. ``cosim identify`` is its command line.
"""

from __future__ import annotations

from cosim.identification.data import IdentificationError
from cosim.identification.model import IdentifiedModel
from cosim.identification.procedure import IdentificationSettings, identify

__all__ = ["IdentificationError", "IdentificationSettings", "IdentifiedModel", "identify"]
