"""The wheel-speed model's slip (estimation.wheel_slip): by hand, and against the plant's
wheels on a circuit with braking zones."""

from __future__ import annotations

import collections
import math
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from cosim.core.physical_constants import AIR_DENSITY_KGPM3, GRAVITY_MPS2
from cosim.core.vehicle_params import PlantConfig, VehicleParams
from cosim.log.reader import iter_messages
from cosim.plant.tyre_model import pure_longitudinal_force_n
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config
from estimation.bicycle import BicycleParams, axle_forces
from estimation.config import EstimatorConfig
from estimation.measurement_models import build_measurement_models
from estimation.state import STATE_NAMES, named_states
from estimation.wheel_slip import WheelLoads, slip_of_force_ratio
from tests.estimation.test_models import _state

BELIEF = VehicleParams()
SLIP = EstimatorConfig().wheel_slip_per_force_ratio


def _spins(belief: VehicleParams, slip: float, combined: float = 0.0,
           **state: float) -> np.ndarray:
    model = build_measurement_models(belief, 0.05, 0.5, wheel_slip_per_force_ratio=slip,
                                     wheel_slip_combined_stiffness_1prad=combined)
    return model["wheel_speed"].evaluate(_state(**state))[0]


def _saturation(config: EstimatorConfig) -> tuple[float, float, float]:
    return (config.wheel_slip_peak_force_ratio, config.wheel_slip_shape,
            config.wheel_slip_curvature)


@pytest.mark.parametrize("kappa", [0.002, 0.02, 0.05, 0.07, -0.03, -0.06])
def test_near_the_peak_the_slip_is_the_plant_tyres_own(kappa: float) -> None:
    """(S1') inverts the Magic Formula's longitudinal curve: the force the plant's default
    tyre gives at its nominal load for a slip ``kappa`` (up to 96 % of its peak) gives that
    slip back, with the estimator's default belief; the linear law (S1) misses it by up to
    a third."""
    tyre = PlantConfig().tyre
    config = EstimatorConfig()
    loads = WheelLoads.from_vehicle(BELIEF, config.wheel_slip_per_force_ratio, 0.0,
                                    _saturation(config))
    ratio = pure_longitudinal_force_n(tyre, kappa, tyre.nominal_load_n, 1.0) \
        / tyre.nominal_load_n
    assert abs(ratio) < 0.96
    r = ca.SX.sym("r")
    slip = float(ca.Function("slip", [r], [slip_of_force_ratio(r, loads)])(ratio))
    assert slip == pytest.approx(kappa, rel=1e-9)
    linear = config.wheel_slip_per_force_ratio * ratio
    assert abs(linear / kappa - 1) < (0.02 if abs(kappa) < 0.01 else 1.0)


def test_the_filter_reads_a_hard_braking_wheel_with_the_tyres_curve() -> None:
    """Braking at 6 m/s^2 (the front wheels near 60 % of their peak): with the estimator's
    default belief the front wheels' slip is (S1')'s, more than (S1)'s for the same force."""
    config = EstimatorConfig()
    state = {"vx_mps": 20.0, "ax_mps2": -6.0}
    free = _spins(BELIEF, 0.0, **state)[:2]
    linear = _spins(BELIEF, SLIP, **state)[:2] / free - 1
    models = build_measurement_models(BELIEF, 0.05, 0.5, wheel_slip_per_force_ratio=SLIP,
                                      wheel_slip_saturation=_saturation(config))
    curved = models["wheel_speed"].evaluate(_state(**state))[0][:2] / free - 1
    loads = WheelLoads.from_vehicle(BELIEF, SLIP, 0.0, _saturation(config))
    r = ca.SX.sym("r")
    inverse = ca.Function("slip", [r], [slip_of_force_ratio(r, loads)])
    np.testing.assert_allclose(curved, [float(inverse(k / SLIP)) for k in linear], rtol=1e-9)
    assert np.all(curved < linear * 1.05)  # more slip (both negative): 5 % and more


def test_a_wheel_slipping_sideways_slips_more_for_the_same_force() -> None:
    """Braking at 2 m/s^2, unsteered, the car sliding sideways at 0.5 m/s: each front wheel's
    slip angle is atan(-0.5 / 20), and its slip is the straight wheel's times
    sqrt(1 + (B alpha)^2), the Magic Formula's combined-slip weight inverted (S1)."""
    state = {"vx_mps": 20.0, "vy_mps": -0.5, "ax_mps2": -2.0}
    combined = EstimatorConfig().wheel_slip_combined_stiffness_1prad
    free = _spins(BELIEF, 0.0, **state)[:2]
    plain = _spins(BELIEF, SLIP, **state)[:2] / free - 1
    sliding = _spins(BELIEF, SLIP, combined, **state)[:2] / free - 1
    factor = math.sqrt(1.0 + (combined * math.atan(-0.5 / 20.0)) ** 2)
    np.testing.assert_allclose(sliding, plain * factor, rtol=1e-9)
    assert factor > 1.04  # some 5 % more slip at 1.4 degrees


def test_a_braking_cars_front_wheels_slip_by_hand() -> None:
    """Straight at 20 m/s braking at 2 m/s^2: the tyres deliver m_e a + drag + rolling
    resistance, the front wheels b/2 of it each (less what turns the wheel), on a load
    raised by the pitch transfer; they spin slower by kappa = c F_x / F_z."""
    m, inertia_mass = BELIEF.mass_kg, BELIEF.wheel_inertia_kgm2 / BELIEF.wheel_radius_m**2
    total = ((m + 4 * inertia_mass) * -2.0 + 0.5 * AIR_DENSITY_KGPM3 * BELIEF.drag_area_m2 * 400
             + BELIEF.rolling_resistance * m * GRAVITY_MPS2 * np.tanh(200.0))
    force = 0.5 * BELIEF.brake_front_share * total + inertia_mass * -2.0
    load = 0.5 * m * (GRAVITY_MPS2 * BELIEF.cog_rear_m + 2.0 * BELIEF.cog_height_m) \
        / BELIEF.wheelbase_m
    kappa = SLIP * force / load
    free = _spins(BELIEF, 0.0, vx_mps=20.0, ax_mps2=-2.0)
    np.testing.assert_allclose(_spins(BELIEF, SLIP, vx_mps=20.0, ax_mps2=-2.0),
                               free * (1 + kappa), rtol=1e-12)
    assert -0.013 < kappa < -0.008  # about 1 %, as the plant's front wheels slip


def test_a_steered_axles_cornering_drag_is_not_braked_by_the_wheels() -> None:
    """Braking at 1 m/s^2 through a left turn with the wheels steered 3 deg and a side slip:
    part of the deceleration is the front tyres' lateral force along the car, F_yf sin(delta),
    which no brake torque makes. The tyres' longitudinal forces are m_e a + the road loads +
    that drag (S2), so the front wheels slip less than a's braking alone would make them:
    kappa by hand from the bicycle's own F_yf."""
    state = {"vx_mps": 20.0, "vy_mps": -0.3, "yaw_rate_radps": 0.2, "ax_mps2": -1.0,
             "steer_rad": math.radians(3.0)}
    x = ca.SX.sym("x", len(STATE_NAMES))
    force_front = float(ca.Function("f", [x], [axle_forces(
        named_states(x), BicycleParams.from_vehicle(BELIEF))[0]])(_state(**state)))
    drag_n = force_front * math.sin(state["steer_rad"])
    assert drag_n > 150.0  # a real part of the braking: m a is some 1,500 N here
    m, inertia_mass = BELIEF.mass_kg, BELIEF.wheel_inertia_kgm2 / BELIEF.wheel_radius_m**2
    total = ((m + 4 * inertia_mass) * -1.0 + 0.5 * AIR_DENSITY_KGPM3 * BELIEF.drag_area_m2 * 400
             + BELIEF.rolling_resistance * m * GRAVITY_MPS2 * np.tanh(200.0) + drag_n)
    force = 0.5 * BELIEF.brake_front_share * total + inertia_mass * -1.0
    lever, track = BELIEF.cog_rear_m, BELIEF.axle_tracks_m[0]
    roll = np.array([-1.0, 1.0]) * state["yaw_rate_radps"] * 20.0 * BELIEF.cog_height_m * lever
    load = m * (0.5 * (GRAVITY_MPS2 * lever + 1.0 * BELIEF.cog_height_m) + roll / track) \
        / BELIEF.wheelbase_m
    kappa = SLIP * force / load  # left (inner), right
    spins = _spins(BELIEF, SLIP, **state)[:2] / _spins(BELIEF, 0.0, **state)[:2] - 1
    np.testing.assert_allclose(spins, kappa, rtol=1e-9)
    braking_alone = SLIP * (force - 0.5 * BELIEF.brake_front_share * drag_n) / load
    assert np.all(np.abs(spins) < 0.9 * np.abs(braking_alone))  # some 15 % less


def test_the_inner_wheel_slips_more_and_a_driven_wheel_forward() -> None:
    braking_in_a_left_turn = {"vx_mps": 20.0, "yaw_rate_radps": 0.15, "ax_mps2": -1.5}
    left, right = _spins(BELIEF, SLIP, **braking_in_a_left_turn) \
        / _spins(BELIEF, 0.0, **braking_in_a_left_turn) - 1
    assert left < right < 0  # the inner (left) wheel is the lighter one
    # A rear-wheel drive's free front wheels do not slip forward when it accelerates; an
    # all-wheel drive's wheels do.
    rwd = _spins(BELIEF, SLIP, vx_mps=20.0, ax_mps2=2.0) / _spins(BELIEF, 0.0, vx_mps=20.0,
                                                                    ax_mps2=2.0) - 1
    awd_belief = VehicleParams(drive="awd")
    awd = _spins(awd_belief, SLIP, vx_mps=20.0, ax_mps2=2.0) \
        / _spins(awd_belief, 0.0, vx_mps=20.0, ax_mps2=2.0) - 1
    assert np.all(np.abs(rwd) < 5e-4) and np.all(awd > 2e-3)


def _wheel_updates(tmp_path: Path, *overrides: str) -> tuple[collections.Counter[str], float]:
    config = load_config("track", overrides=["seed=8500", "sim.duration_s=12", *overrides])
    result = run(config, tmp_path / "track.mcap")
    reasons = collections.Counter(m["reason"] for _, m in iter_messages(
        tmp_path / "track.mcap", "/estimator/updates") if m["sensor"] == "wheel_speed")
    return reasons, float(result.metrics["nis_settled_wheel_speed"])


@pytest.mark.slow
def test_the_circuits_braking_zones_do_not_gate_the_wheels(tmp_path: Path) -> None:
    """The ring's first 12 s (two braking zones, one in a turn), a seed no tuning used: with
    the slip every wheel-speed update is fused and the NIS per dof is about 1; rolling freely
    (the model before), the braking zones gate the front wheels and the NIS doubles."""
    reasons, nis = _wheel_updates(tmp_path)
    assert reasons["accepted"] >= 0.99 * sum(reasons.values()), reasons
    assert 0.7 < nis < 1.4
    free, free_nis = _wheel_updates(tmp_path, "estimator.wheel_slip_per_force_ratio=0")
    assert free["accepted"] < 0.98 * sum(free.values()), free
    assert free_nis > 1.6


@pytest.mark.slow
def test_the_tyres_loaded_radius_is_the_plants_rolling_radius() -> None:
    """With the tyre's vertical compliance the plant's static equilibrium gives (its loaded
    rolling radius short of the unloaded one, per newton of its static load), the filter's
    model of a free-rolling front wheel spins as the plant's does: on the straight, in a
    swerve and in the launch, within 0.1 % where the unloaded radius is 0.15-0.35 % off (a
    model without the load's term, or with the compliance's sign turned, fails)."""
    from cosim.log.recorder import NoLog
    from cosim.simulation.runner import RunState
    from cosim.simulation.workshop import Workshop

    config = load_config("lane-change")
    run_state = RunState(config, NoLog(), workshop=Workshop())
    plant = run_state.plant
    compliance = [(config.plant.wheel_radius_m - radius) / load for radius, load
                  in zip(plant.rolling_radius_m, plant.static_wheel_load_n, strict=True)]
    assert compliance[0] == pytest.approx(compliance[2], rel=0.02)  # one tyre, both axles
    estimator = EstimatorConfig()
    models = {c: build_measurement_models(
        config.tracker.model, 0.002, 0.0, wheel_slip_per_force_ratio=SLIP,
        wheel_slip_combined_stiffness_1prad=estimator.wheel_slip_combined_stiffness_1prad,
        wheel_slip_saturation=_saturation(estimator), tyre_vertical_compliance_mpn=c)
        for c in (0.0, compliance[0])}
    step, ended, errors = 0, False, {}
    while not ended and len(errors) < 3:
        step, ended = run_state.advance(step, observed=True, pause_at_control=True)
        truth = run_state.truth
        if any(abs(truth.t_s - t) < 1e-9 for t in (1.0, 3.95, 10.0)):  # launch, swerve, straight
            x = _state(vx_mps=truth.vx_mps, vy_mps=truth.vy_mps, ax_mps2=truth.ax_mps2,
                       yaw_rate_radps=truth.yaw_rate_radps, steer_rad=truth.steer_rad)
            errors[truth.t_s] = {c: model["wheel_speed"].evaluate(x)[0][:2]
                                 / np.array(truth.wheel_speed_radps[:2]) - 1.0
                                 for c, model in models.items()}
    assert len(errors) == 3
    for error in errors.values():
        assert np.all(np.abs(error[compliance[0]]) < 1e-3), errors
        assert np.all(np.abs(error[0.0]) > 1.4e-3), errors
