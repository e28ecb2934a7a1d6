"""The tyre model's curves and contact-patch dynamics, with numbers a reader can check.

Default tyre (Pacejka 2006, Table A3.1, 205/60R15) at its nominal load F_z0 = 4000 N:
cornering stiffness K_ya = 14.95 * 4000 * sin(2 atan(1 / 2.13)) = 46 009 N/rad, slip
stiffness K_xk = 21.51 * 4000 = 86 040 N; relaxation lengths K / c: 86 040 / 450 000 =
0.191 m and 46 009 / 160 000 = 0.288 m.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest

from cosim.core.tyre_params import TyreParams
from cosim.plant.tyre_model import (
    PATCH_AT_REST,
    PatchState,
    combined_forces_n,
    combined_weights,
    cornering_stiffness_nprad,
    patch_step,
    pure_lateral_force_n,
    pure_longitudinal_force_n,
    relaxation_lengths_m,
    slip_stiffness_n,
)

TYRE = TyreParams()
LOADS_N = (1000.0, 3300.0, 4000.0, 4400.0, 7000.0)
FRICTIONS = (1.0, 0.5, 0.3)
DT_S = 0.002


def test_stiffnesses_at_nominal_load() -> None:
    assert cornering_stiffness_nprad(TYRE, 4000.0) == pytest.approx(46009.1, abs=0.1)
    assert slip_stiffness_n(TYRE, 4000.0) == pytest.approx(86040.0)
    assert relaxation_lengths_m(TYRE, 4000.0) == pytest.approx((0.1912, 0.2876), abs=1e-4)
    assert cornering_stiffness_nprad(TYRE, 0.0) == 0.0 and slip_stiffness_n(TYRE, 0.0) == 0.0


def test_cornering_stiffness_grows_sub_linearly_with_load() -> None:
    stiffness = [cornering_stiffness_nprad(TYRE, load) for load in LOADS_N]
    per_load = [k / load for k, load in zip(stiffness, LOADS_N, strict=True)]
    assert all(b > a for a, b in itertools.pairwise(stiffness))
    assert all(b < a for a, b in itertools.pairwise(per_load))
    # Held at its maximum p_Ky1 F_z0 = 59 800 N/rad above p_Ky2 F_z0 = 8520 N.
    assert cornering_stiffness_nprad(TYRE, 12000.0) == pytest.approx(14.95 * 4000.0)


@pytest.mark.parametrize("load_n", LOADS_N)
@pytest.mark.parametrize("friction", FRICTIONS)
def test_pure_slip_peak_is_mu_times_load(load_n: float, friction: float) -> None:
    slips = np.linspace(0.0, 1.0, 20001)
    longitudinal = [pure_longitudinal_force_n(TYRE, s, load_n, friction) for s in slips]
    lateral = [pure_lateral_force_n(TYRE, s, load_n, friction) for s in slips]
    assert max(longitudinal) == pytest.approx(friction * load_n, rel=1e-4)
    assert max(lateral) == pytest.approx(friction * load_n, rel=1e-4)
    assert max(longitudinal) <= friction * load_n and max(lateral) <= friction * load_n


@pytest.mark.parametrize("load_n", LOADS_N)
@pytest.mark.parametrize("friction", FRICTIONS)
def test_slope_at_zero_slip_is_the_stiffness_whatever_the_friction(
    load_n: float, friction: float
) -> None:
    eps = 1e-7
    slope_x = (pure_longitudinal_force_n(TYRE, eps, load_n, friction)
               - pure_longitudinal_force_n(TYRE, -eps, load_n, friction)) / (2 * eps)
    slope_y = (pure_lateral_force_n(TYRE, eps, load_n, friction)
               - pure_lateral_force_n(TYRE, -eps, load_n, friction)) / (2 * eps)
    assert slope_x == pytest.approx(slip_stiffness_n(TYRE, load_n), rel=1e-6)
    assert slope_y == pytest.approx(cornering_stiffness_nprad(TYRE, load_n), rel=1e-6)


def test_curves_are_odd_and_forces_oppose_the_slip() -> None:
    for slip, load in itertools.product(np.linspace(0.001, 2.0, 37), LOADS_N):
        fx = pure_longitudinal_force_n(TYRE, slip, load, 1.0)
        fy = pure_lateral_force_n(TYRE, slip, load, 1.0)
        assert fx > 0.0 and fy > 0.0
        assert pure_longitudinal_force_n(TYRE, -slip, load, 1.0) == -fx
        assert pure_lateral_force_n(TYRE, -slip, load, 1.0) == -fy
    for kappa, alpha in itertools.product((-0.5, -0.05, 0.02, 0.3), (-0.3, -0.02, 0.05, 0.2)):
        fx, fy = combined_forces_n(TYRE, kappa, alpha, 4000.0, 1.0)
        assert combined_forces_n(TYRE, -kappa, alpha, 4000.0, 1.0) == (-fx, fy)
        assert combined_forces_n(TYRE, kappa, -alpha, 4000.0, 1.0) == (fx, -fy)
        assert math.copysign(1.0, fx) == math.copysign(1.0, kappa)
        assert math.copysign(1.0, fy) == math.copysign(1.0, alpha)


def test_combined_slip_never_leaves_the_friction_circle() -> None:
    kappas = np.linspace(-2.0, 2.0, 81)
    tan_alphas = np.linspace(-1.0, 1.0, 81)
    for load, friction in itertools.product(LOADS_N, FRICTIONS):
        worst = 0.0
        for kappa, tan_alpha in itertools.product(kappas, tan_alphas):
            fx, fy = combined_forces_n(TYRE, kappa, tan_alpha, load, friction)
            worst = max(worst, math.hypot(fx, fy) / (friction * load))
        assert worst <= 1.0 + 1e-12
        assert worst > 0.99  # and it reaches the circle


def test_combined_slip_reduces_each_force() -> None:
    # Braking at the peak slip ratio takes lateral grip; a locked wheel (k = -1) keeps
    # under a fifth of it (G_yk = cos(1.081 atan(6.461 cos(atan(4.196 a)) k))).
    fy0 = pure_lateral_force_n(TYRE, 0.05, 4000.0, 1.0)
    _, fy_braking = combined_forces_n(TYRE, -0.12, 0.05, 4000.0, 1.0)
    _, fy_locked = combined_forces_n(TYRE, -1.0, 0.05, 4000.0, 1.0)
    assert 0.0 < fy_locked < 0.2 * fy0 and fy_locked < fy_braking < fy0
    fx0 = pure_longitudinal_force_n(TYRE, 0.05, 4000.0, 1.0)
    fx_cornering, _ = combined_forces_n(TYRE, 0.05, 0.1, 4000.0, 1.0)
    assert 0.0 < fx_cornering < fx0


def test_no_load_no_force() -> None:
    assert combined_forces_n(TYRE, 0.1, 0.1, 0.0, 1.0) == (0.0, 0.0)
    assert pure_lateral_force_n(TYRE, 0.1, -5.0, 1.0) == 0.0
    lifted = patch_step(TYRE, 1.0, 0.0, 20.0, -1.0, 1.0, PatchState(0.01, 0.01, 0.0, 0.0),
                        DT_S)
    assert (lifted.force_x_n, lifted.force_y_n, lifted.state) == (0.0, 0.0, PATCH_AT_REST)


def roll(duration_s: float, speed_mps: float, slip_x_mps: float, slip_y_mps: float,
         load_n: float = 4000.0, friction: float = 1.0,
         state: PatchState = PATCH_AT_REST) -> list[tuple[float, float, PatchState]]:
    """The patch under constant kinematics: (force_x, force_y, state) after each step."""
    out = []
    for _ in range(round(duration_s / DT_S)):
        force_x, force_y, state = patch_step(TYRE, friction, load_n, speed_mps, slip_x_mps,
                                             slip_y_mps, state, DT_S)
        out.append((force_x, force_y, state))
    return out


@pytest.mark.parametrize(
    ("kappa", "tan_alpha"), [(0.02, 0.0), (0.0, 0.03), (-0.05, 0.05), (0.3, 0.0), (0.0, 0.4)]
)
def test_steady_rolling_gives_the_steady_state_characteristic(kappa: float,
                                                              tan_alpha: float) -> None:
    # At 20 m/s: slip velocity V_s = -k V (longitudinal), -tan(a) V (lateral).
    force_x, force_y, _ = roll(1.0, 20.0, -kappa * 20.0, -tan_alpha * 20.0)[-1]
    steady_x, steady_y = combined_forces_n(TYRE, kappa, tan_alpha, 4000.0, 1.0)
    assert force_x == pytest.approx(steady_x, rel=2e-3, abs=0.5)
    assert force_y == pytest.approx(steady_y, rel=2e-3, abs=0.5)


@pytest.mark.parametrize("speed_mps", [5.0, 20.0])
def test_lateral_force_builds_up_over_the_relaxation_length(speed_mps: float) -> None:
    # After a step to a small slip angle the force reaches 1 - 1/e = 63 % of its steady
    # value once the wheel has rolled sigma_a = 0.288 m (plus d v / c = 100 * v / 160 000).
    steps = roll(1.0, speed_mps, 0.0, -0.01 * speed_mps)
    steady = steps[-1][1]
    k63 = next(k for k, (_, force_y, _) in enumerate(steps) if force_y >= 0.632 * steady)
    distance_m = (k63 + 1) * DT_S * speed_mps
    expected = 0.2876 + 100.0 * speed_mps / 160000.0
    assert distance_m == pytest.approx(expected, abs=speed_mps * DT_S + 0.01)


def test_standstill_patch_is_a_spring_without_singularity() -> None:
    # At V_cx = 0 the patch sticks to the road: pushed sideways at 1 mm/s for 0.5 s
    # (0.5 mm) the tyre is a spring c_y = 160 kN/m and damper d = 100 + 5000 N s/m to the
    # ground, relaxed only by the slip-speed floor v_N = 0.1 m/s at the rate
    # a = c v_N / (d v_N + K) = 16 000 / (510 + 46 009) = 0.344 /s. Deflection
    # e(t) = -(b V_s / a)(1 - exp(-a t)), b = K / (d v_N + K) = 0.989: -0.455 mm at 0.5 s,
    # force c e + d de/dt = -72.8 - 4.2 = -77.0 N (a pure spring would give -80 - 5.1).
    steps = roll(0.5, 0.0, 0.0, 0.001)
    assert steps[-1][1] == pytest.approx(-77.0, rel=0.01)
    # Released (no slip velocity) it holds its deflection, creeping back at 0.344 /s:
    # after 1 s, exp(-0.344) = 71 % of it is left, force (c - d a) e = 0.989 c e:
    # -72.8 * 0.709 * 0.989 = -51.0 N.
    held = roll(1.0, 0.0, 0.0, 0.0, state=steps[-1][2])
    assert held[-1][1] == pytest.approx(-51.0, rel=0.01)
    assert all(np.isfinite([fy for _, fy, _ in steps + held]))


def test_sliding_at_standstill_saturates_without_wind_up() -> None:
    # Dragged sideways at 0.2 m/s for 1 s with 4000 N of load: the force is the friction
    # limit (sliding), and the carcass holds only about mu F_z / c_y = 25 mm, not 0.2 m.
    steps = roll(1.0, 0.0, 0.0, 0.2)
    force_y = [f for _, f, _ in steps]
    assert min(force_y) >= -4000.0 - 1e-9
    assert force_y[-1] < -0.9 * 4000.0
    assert abs(steps[-1][2].deflection_y_m) < 1.1 * 4000.0 / 160000.0
    # Let go: the stored deflection releases at most its elastic energy, the force never
    # exceeds the limit and decays.
    released = roll(0.5, 0.0, 0.0, 0.0, state=steps[-1][2])
    assert max(abs(f) for _, f, _ in released) <= 4000.0


def test_locked_wheel_slides_at_the_tail_of_the_curve() -> None:
    # A locked wheel at 20 m/s: k = -1, the MF tail: 0.63 mu F_z.
    force_x, _, _ = roll(0.5, 20.0, 20.0, 0.0)[-1]
    assert force_x == pytest.approx(pure_longitudinal_force_n(TYRE, -1.0, 4000.0, 1.0),
                                    rel=1e-3)
    assert force_x == pytest.approx(-0.632 * 4000.0, rel=0.01)


@pytest.mark.parametrize("load_n", LOADS_N)
def test_peak_friction_falls_with_load_by_the_slope(load_n: float) -> None:
    """``tyre.peak_friction_load_slope = -0.2``: the peak is ``mu (1 - 0.2 df_z) F_z``
    (Pacejka 2012, 4.E13, 4.E23): at 7000 N (df_z = 0.75) 0.85 mu F_z, at 1000 N 1.15."""
    tyre = dataclasses.replace(TYRE, peak_friction_load_slope=-0.2)
    dfz = (load_n - TYRE.nominal_load_n) / TYRE.nominal_load_n
    expected = 0.9 * load_n * (1.0 - 0.2 * dfz)
    slips = np.linspace(0.0, 1.0, 20001)
    longitudinal = max(pure_longitudinal_force_n(tyre, s, load_n, 0.9) for s in slips)
    lateral = max(pure_lateral_force_n(tyre, s, load_n, 0.9) for s in slips)
    assert longitudinal == pytest.approx(expected, rel=1e-4)
    assert lateral == pytest.approx(expected, rel=1e-4)
    force = combined_forces_n(tyre, 0.5, 0.5, load_n, 0.9)
    assert math.hypot(*force) <= expected * (1.0 + 1e-12)


MU_X_SCALE, MU_Y_SCALE = 1.21, 0.99
"""Pacejka's reference tyre's own peak frictions (Table A3.1: p_Dx1 1.21, p_Dy1 0.99) as
the scales lambda_mux, lambda_muy of friction 1."""


@pytest.mark.parametrize("load_n", LOADS_N)
def test_friction_scales_set_each_directions_peak_not_the_stiffness(load_n: float) -> None:
    """``lambda_mux`` = 1.21, ``lambda_muy`` = 0.99 with ``tyre_friction`` 0.8: the peaks are
    0.968 F_z ahead and 0.792 F_z sideways (Pacejka 2012, 4.E13, 4.E23); the slopes at zero
    slip (K = B C D) stay those of the tyre."""
    tyre = dataclasses.replace(TYRE, longitudinal_friction_scale=MU_X_SCALE,
                               lateral_friction_scale=MU_Y_SCALE)
    slips = np.linspace(0.0, 1.0, 20001)
    longitudinal = max(pure_longitudinal_force_n(tyre, s, load_n, 0.8) for s in slips)
    lateral = max(pure_lateral_force_n(tyre, s, load_n, 0.8) for s in slips)
    assert longitudinal == pytest.approx(0.8 * MU_X_SCALE * load_n, rel=1e-4)
    assert lateral == pytest.approx(0.8 * MU_Y_SCALE * load_n, rel=1e-4)
    eps = 1e-7
    for force, stiffness in ((pure_longitudinal_force_n, slip_stiffness_n(tyre, load_n)),
                             (pure_lateral_force_n, cornering_stiffness_nprad(tyre, load_n))):
        slope = (force(tyre, eps, load_n, 0.8) - force(tyre, -eps, load_n, 0.8)) / (2 * eps)
        assert slope == pytest.approx(stiffness, rel=1e-6)


def test_combined_forces_stay_within_the_friction_ellipse() -> None:
    """With ``lambda_mux`` 1.21 and ``lambda_muy`` 0.99 the combined force reaches the
    ellipse ``(F_x / D_x)^2 + (F_y / D_y)^2 = 1`` where the slips are large and never leaves
    it; a force the isotropic circle of radius D_y would have cut (longitudinal, beyond
    D_y) passes."""
    tyre = dataclasses.replace(TYRE, longitudinal_friction_scale=MU_X_SCALE,
                               lateral_friction_scale=MU_Y_SCALE)
    load, friction = 4000.0, 0.8
    peak_x, peak_y = friction * MU_X_SCALE * load, friction * MU_Y_SCALE * load
    largest = 0.0
    for kappa, tan_alpha in itertools.product(np.linspace(-1.0, 1.0, 41),
                                              np.linspace(-1.0, 1.0, 41)):
        fx, fy = combined_forces_n(tyre, kappa, tan_alpha, load, friction)
        usage = (fx / peak_x) ** 2 + (fy / peak_y) ** 2
        assert usage <= 1.0 + 1e-12
        largest = max(largest, usage)
    assert largest == pytest.approx(1.0)
    fx, _ = combined_forces_n(tyre, 0.12, 0.001, load, friction)
    assert fx > 1.05 * peak_y


def test_isotropic_scales_leave_the_friction_circle_bit_for_bit() -> None:
    """Scales of 1 (the default) are the tyre as it was before them: the weighted pure-slip
    forces, scaled onto the circle of radius ``mu (1 + p_D2 df_z) F_z`` when outside it,
    to the last bit (so a default run is unchanged)."""
    tyre = dataclasses.replace(TYRE, peak_friction_load_slope=-0.1)
    rng = np.random.default_rng(7)
    cut = 0
    for _ in range(400):
        kappa, tan_alpha = rng.normal(0.0, 0.3, 2)
        load = float(rng.uniform(500.0, 8000.0))
        g_xa, g_yk = combined_weights(tyre, kappa, tan_alpha)
        fx = g_xa * pure_longitudinal_force_n(tyre, kappa, load, 0.7)
        fy = g_yk * pure_lateral_force_n(tyre, tan_alpha, load, 0.7)
        dfz = (load - tyre.nominal_load_n) / tyre.nominal_load_n
        limit = 0.7 * load * (1.0 + tyre.peak_friction_load_slope * dfz)
        magnitude2 = fx * fx + fy * fy
        if magnitude2 > limit * limit:
            scale = limit / math.sqrt(magnitude2)
            fx, fy = fx * scale, fy * scale
            cut += 1
        assert combined_forces_n(tyre, kappa, tan_alpha, load, 0.7) == (fx, fy)
    assert cut > 20  # the circle's cut is exercised, not only the inside
