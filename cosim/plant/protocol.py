"""The interface of the plant: the simulated car the runner steps (the truth).

:class:`cosim.plant.car.MujocoPlant` is the one built in. A tracker never sees the plant;
the runner reads the truth from :meth:`Plant.state` and hands the plant only what reaches a
real car: actuator commands after the delay line and the low-level layer, and unmeasured
disturbances.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from cosim.core.records import ActuatorCommand, VehicleState
from cosim.plant.tyre_forces import TyreForces


@runtime_checkable
class Plant(Protocol):
    """The simulated car, stepped at ``physics_dt_s``."""

    physics_dt_s: float
    mjcf_xml: str
    """The model actually simulated (attached to the log)."""

    def reset(self) -> None:
        """Back to the initial state, at rest on its suspension."""

    def apply(self, actuator: ActuatorCommand) -> None:
        """Set the actuators' targets (wheel torques, road-wheel angle); they act from the
        next :meth:`advance` on. The tracker's :class:`~cosim.core.records.Command` reaches
        the plant through the delay line and the low-level layer
        (:mod:`cosim.plant.low_level`)."""

    def advance(self) -> None:
        """Advance the physics by one step of ``physics_dt_s``; a diverging simulation
        raises :class:`~cosim.core.exceptions.PhysicsDivergenceError`."""

    def advance_steps(self, n: int) -> None:
        """:meth:`advance` ``n`` times (the runner calls it between the steps at which
        something is due; a plant may do them in one call)."""

    def state(self) -> VehicleState:
        """The true state now."""

    def tyre_forces(self) -> tuple[TyreForces, ...] | None:
        """Each tyre's load, slip and forces of the last step, or None when the plant does
        not model them apart (the outcome monitor reads the loads for wheel lift)."""

    def add_yaw_rate(self, delta_radps: float) -> None:
        """An unmeasured yaw disturbance (:mod:`cosim.plant.disturbances`)."""
