"""What a car's data sheet tells its controller and its filter, beside what identification fits.

:func:`cosim.identification.identify` fits the bicycle model (mass, yaw inertia, CoG, axle
cornering stiffnesses, steering lag) from the car's response. The rest of a belief is read
off the car's data sheet, as an engineer would read it off the manufacturer's:

* the controller's (``tracker.model.*``): the figures of the car that the fitted model does
  not hold (tracks, CoG height, wheel radius and spin inertia, steering limits ...), where
  they differ from what the controller believes otherwise (not the road's friction);
* the filter's (``estimator.*``), derived from the car's tyre, steering and suspension:

  - the tyre's: each axle's load sensitivity of its cornering stiffness,
    ``d ln K_ya / d ln F_z`` at the static wheel load (Pacejka, *Tyre and Vehicle
    Dynamics*, 3rd ed. 2012, (4.E25)), its relaxation length ``K_ya / c_y`` (times the
    axle's cornering-stiffness scale), the longitudinal peak force per load on the road
    the controller believes in (:mod:`cosim.plant.tyre_model`), and the coefficients of its
    longitudinal slip curve that the wheel-speed model inverts (``p_Kx1``, ``r_Bx1``,
    ``p_Cx1``, ``p_Ex1``; :mod:`estimation.wheel_slip`);
  - the steering's compliance: one over the stiffness of the front wheels about the
    steering axis (the steering servo's gain, :func:`cosim.plant.sedan_model.sedan_layout`);
  - the suspension's roll mode: gradient, natural frequency and damping ratio of the body
    on its springs and anti-roll bars (:func:`cosim.plant.roll_mode.roll_mode`).

``cosim identify --belief-out`` writes both beside the fitted model, so that a user's own
car, like the published ones (``cosim/cars/``), runs with a filter that knows its tyres,
steering and roll rather than the default sedan's; a sampled sedan
(:mod:`cosim.plant.sedan_sampler`, ``vehicle_sample``) gives its filter its own the same way.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection
from dataclasses import dataclass

from cosim.core.exceptions import ConfigError
from cosim.core.vehicle_params import PlantConfig, VehicleParams

NOT_ON_THE_DATA_SHEET = ("tyre_friction",)
"""Shared fields that are not the car's: the road's friction (a belief of its own,
``tracker.model.tyre_friction``, which a car identified on a wet road must not take)."""


ESTIMATOR_SOURCES = ("from its tyre's: the estimator's tyre_load_sensitivity_*, "
                     "tyre_relaxation_length_* and wheel_slip_*; from its steering's: "
                     "steering_compliance_radpnm; from its suspension's: "
                     "roll_gradient_radpmps2, roll_frequency_hz, roll_damping_ratio")
"""Where each of :attr:`DataSheetBelief.estimator`'s keys comes from, as a belief file's
header says it."""


@dataclass(frozen=True)
class DataSheetBelief:
    """The belief a car's data sheet gives, as belief-file keys."""

    model: dict[str, float | str]
    """``tracker.model.*`` keys: the car's figures that differ from the controller's."""
    estimator: dict[str, float]
    """``estimator.*`` keys: tyre, steering and roll beliefs (module docstring)."""


def data_sheet_belief(plant: PlantConfig, believed: VehicleParams,
                      fitted: Collection[str]) -> DataSheetBelief:
    """The data sheet's belief of ``plant`` for a controller that believes ``believed``,
    whose ``fitted`` keys identification gives (those are left to the fit). A car whose
    springs cannot hold its body up in roll is a :class:`ConfigError`."""
    model = {name: getattr(plant, name) for name in shared_figures()
             if name not in fitted and name not in NOT_ON_THE_DATA_SHEET
             and getattr(plant, name) != getattr(believed, name)}
    return DataSheetBelief(model, {**tyre_beliefs(plant, believed.tyre_friction),
                                   **steering_belief(plant), **roll_belief(plant)})


def shared_figures() -> tuple[str, ...]:
    """The fields the controller's model (:class:`VehicleParams`) and the plant share."""
    plant = {f.name for f in dataclasses.fields(PlantConfig)}
    return tuple(f.name for f in dataclasses.fields(VehicleParams) if f.name in plant)


def tyre_beliefs(plant: PlantConfig, friction: float) -> dict[str, float]:
    """``estimator.tyre_load_sensitivity_front``, ``_rear``,
    ``tyre_relaxation_length_front_m``, ``_rear_m`` (at the static front and rear wheel
    loads), ``wheel_slip_peak_force_ratio`` (at the static front load, on a road of the
    believed ``friction``: the road is not on the car's data sheet) and the slip curve's
    ``wheel_slip_per_force_ratio``, ``_combined_stiffness_1prad``, ``_shape``,
    ``_curvature``."""
    from cosim.plant.tyre_model import (
        cornering_stiffness_load_elasticity,
        peak_forces_n,
        relaxation_lengths_m,
    )

    tyre = plant.tyre
    axles = tuple(zip(("front", "rear"), plant.static_wheel_loads_n,
                      (plant.front_cornering_stiffness_scale,
                       plant.rear_cornering_stiffness_scale), strict=True))
    beliefs = {f"tyre_load_sensitivity_{axle}":
               round(cornering_stiffness_load_elasticity(tyre, load), 2)
               for axle, load, _ in axles}
    beliefs.update({f"tyre_relaxation_length_{axle}_m":
                    round(relaxation_lengths_m(tyre, load)[1] * scale, 3)
                    for axle, load, scale in axles})
    front_load = plant.static_wheel_loads_n[0]
    beliefs["wheel_slip_peak_force_ratio"] = round(
        peak_forces_n(tyre, front_load, friction)[0] / front_load, 3)
    # The wheel-speed model's slip curve is the tyre's longitudinal Magic Formula
    # (estimation.wheel_slip): its coefficients as they are.
    beliefs.update({"wheel_slip_per_force_ratio": 1.0 / tyre.slip_stiffness_per_load,
                    "wheel_slip_combined_stiffness_1prad": tyre.combined_x_stiffness,
                    "wheel_slip_shape": tyre.longitudinal_shape,
                    "wheel_slip_curvature": tyre.longitudinal_curvature})
    return beliefs


def steering_belief(plant: PlantConfig) -> dict[str, float]:
    """``estimator.steering_compliance_radpnm``: one over the gain of the steering servo."""
    from cosim.plant.sedan_model import sedan_layout

    return {"steering_compliance_radpnm":
            float(f"{1.0 / sedan_layout(plant).steer_servo_kp_nmprad:.4g}")}


def roll_belief(plant: PlantConfig) -> dict[str, float]:
    """``estimator.roll_gradient_radpmps2``, ``roll_frequency_hz`` and
    ``roll_damping_ratio``: the roll mode of the body on its suspension."""
    from cosim.plant.roll_mode import roll_mode
    from cosim.plant.sedan_model import sedan_layout

    try:
        mode = roll_mode(sedan_layout(plant, plant.suspension), plant.suspension)
    except ValueError as error:
        raise ConfigError(f"plant.suspension: {error}") from None
    return {"roll_gradient_radpmps2": float(f"{mode.gradient_radpmps2:.3g}"),
            "roll_frequency_hz": float(f"{mode.frequency_hz:.3g}"),
            "roll_damping_ratio": float(f"{mode.damping_ratio:.2g}")}
