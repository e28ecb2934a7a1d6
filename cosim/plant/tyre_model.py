"""Tyre forces: Magic Formula characteristics and a first-order (relaxing) contact patch.

Pure functions on plain floats, called for each of the four tyres at every physics step.

**Steady state** is Pacejka's Magic Formula (H. B. Pacejka, *Tyre and Vehicle Dynamics*, 3rd
ed., 2012, §4.3.2, the MF 6.1 equations 4.E1-4.E67) reduced to what a flat road and a car
without camber need: no camber, turn slip, inflation pressure, horizontal or vertical shifts.

- pure longitudinal slip (4.E9-4.E18)::

      F_x0 = D_x sin(C_x atan(B_x k - E_x (B_x k - atan(B_x k))))
      D_x = mu lambda_mux (1 + p_D2 df_z) F_z      (4.E13, p_D2 = p_Dx2 / p_Dx1)
      K_xk = F_z (p_Kx1 + p_Kx2 df_z) exp(p_Kx3 df_z),   df_z = (F_z - F_z0) / F_z0   (4.E15)
      B_x = K_xk / (C_x D_x)

- pure lateral slip (4.E19-4.E30), with ``a = tan(alpha)`` (MF 6.1's alpha*)::

      F_y0 = D_y sin(C_y atan(B_y a - E_y (B_y a - atan(B_y a))))
      D_y = mu lambda_muy (1 + p_D2 df_z) F_z      (4.E23, the same relative slope)
      K_ya = p_Ky1 F_z0 sin(2 atan(F_z / (p_Ky2 F_z0)))                           (4.E25)
      B_y = K_ya / (C_y D_y)

  The cornering stiffness grows sub-linearly with load (the argument of the sine is held at
  pi/2 above ``F_z = p_Ky2 F_z0``, where the book's curve would turn down); the peak force is
  ``mu lambda_mu (1 + p_D2 df_z) F_z``: one friction coefficient, ``PlantConfig.tyre_friction``,
  scaled per direction by Pacejka's ``lambda_mux``, ``lambda_muy``
  (``tyre.longitudinal_friction_scale``, ``tyre.lateral_friction_scale``, 1 by default: the
  same peak in both directions), and one relative load slope,
  ``tyre.peak_friction_load_slope`` (0 by default: the peak friction then does not fall
  with load). ``mu`` sets the peak but not the slope at zero slip (``B = K / (C D)``).

- combined slip, the MF weighting functions (4.E50-4.E67, no shifts, no curvature)::

      F_x = G_xa F_x0,  G_xa = cos(r_Cx1 atan(B_xa a)),  B_xa = r_Bx1 cos(atan(r_Bx2 k))
      F_y = G_yk F_y0,  G_yk = cos(r_Cy1 atan(B_yk k)),  B_yk = r_By1 cos(atan(r_By2 a))

  followed by a friction-ellipse guard: if ``(F_x / D_x)^2 + (F_y / D_y)^2 > 1`` both are
  scaled down onto the ellipse (a circle of radius ``mu F_z`` with isotropic friction), so
  the resultant never exceeds the peaks.

Slip signs: ``k = -V_sx / |V_cx|`` and ``tan(alpha) = -V_sy / |V_cx|``, with ``V_s`` the
velocity of the wheel's material point at the contact (the slip velocity) and ``V_cx`` the
forward speed of the wheel centre, both in the wheel's heading frame (ISO 8855 axes: x along
the wheel's heading in the road plane, y to its left). Positive slip gives a positive force:
the force opposes the sliding of the contact patch. The book's ISO table carries negative
``p_Dy1`` and ``p_Ky1`` for the opposite sign of alpha; :class:`TyreParams` holds magnitudes.

**Transient behaviour and low speed** use the tyre carcass as a spring ``c`` and damper ``d``
in series with the sliding contact patch (the single-contact-point model: Pacejka 2012,
ch. 7, where the relaxation length is ``sigma = K / c``; written with a damper and a
"global" slip stiffness as in TMeasy, G. Rill, *Road Vehicle Dynamics*, CRC 2011, ch. 3,
"first-order tyre dynamics"). For each direction, with carcass deflection ``e``::

      F = c e + d de/dt                                  (carcass force on the rim)
      F = f s_eff,  s_eff = -(V_s + de/dt) / v*          (the patch slides at V_s + de/dt)
  =>  de/dt = -(c v* e + f V_s) / (d v* + f)

where ``v* = sqrt(V_cx^2 + v_N^2)`` never vanishes and ``f = F_ss(s_eff) / s_eff`` is the
secant ("global") slope of the steady-state characteristic at the patch's own slip of the
previous step. Rolling steadily, ``de/dt = 0`` and ``F = F_ss``; after a slip step the force
builds up over the relaxation length ``f / c``; at standstill the patch sticks to the road
(``de/dt = -V_s``): the tyre is a spring-damper to the ground, so there is no singular slip
and a car at rest stays at rest; when the force would exceed the characteristic, ``f`` drops
and the deflection collapses to ``F_ss / c`` (sliding). The deflection equation is linear for
a fixed ``f`` and ``V_s`` and is integrated exactly over the step (exponential), so it has no
step-size limit of its own. Below ``low_speed_damping_fade_mps`` an extra damping, faded out
with ``(1 + cos(pi |V_cx| / V_low)) / 2`` (the MF-Tyre low-speed damping), damps the
weakly damped standstill modes (the car swaying on its tyres, the wheels' spin against the
carcass).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

from cosim.core.tyre_params import TyreParams

MIN_LOAD_N = 1.0
"""Below this normal load the tyre carries no force (a wheel in the air) [N]."""

SLIP_EPSILON = 1e-9
"""Slip below which the secant slope is taken as the slope at zero slip [-]."""


class PatchState(NamedTuple):
    """Carcass deflection of one tyre and its rate (wheel heading frame, ISO 8855 axes)."""

    deflection_x_m: float
    deflection_y_m: float
    deflection_rate_x_mps: float
    deflection_rate_y_mps: float


PATCH_AT_REST = PatchState(0.0, 0.0, 0.0, 0.0)
"""An undeflected tyre."""


class PatchForces(NamedTuple):
    """What :func:`patch_step` returns: forces on the wheel and the new carcass state."""

    force_x_n: float
    force_y_n: float
    state: PatchState


def slip_stiffness_n(params: TyreParams, load_n: float) -> float:
    """Longitudinal slip stiffness ``K_xk = F_z (p_Kx1 + p_Kx2 df_z) exp(p_Kx3 df_z)`` (4.E15)
    [N per unit slip ratio]; zero for no load."""
    if load_n <= 0.0:
        return 0.0
    dfz = (load_n - params.nominal_load_n) / params.nominal_load_n
    return (
        load_n
        * (params.slip_stiffness_per_load + params.slip_stiffness_load_slope * dfz)
        * math.exp(params.slip_stiffness_load_exponent * dfz)
    )


def cornering_stiffness_nprad(params: TyreParams, load_n: float) -> float:
    """Cornering stiffness ``K_ya = p_Ky1 F_z0 sin(2 atan(F_z / (p_Ky2 F_z0)))`` (4.E25)
    [N/rad], held at its maximum ``p_Ky1 F_z0`` above ``F_z = p_Ky2 F_z0``; zero for no load."""
    if load_n <= 0.0:
        return 0.0
    ratio = min(load_n / (params.cornering_stiffness_peak_load_ratio * params.nominal_load_n), 1.0)
    # sin(2 atan(x)) = 2 x / (1 + x^2)
    return params.cornering_stiffness_max_prad * params.nominal_load_n * 2.0 * ratio / (
        1.0 + ratio * ratio
    )


def cornering_stiffness_load_elasticity(params: TyreParams, load_n: float) -> float:
    """``d ln K_ya / d ln F_z`` of (4.E25) at the wheel load ``load_n``: ``(1 - u^2) / (1 +
    u^2)`` with ``u = F_z / (p_Ky2 F_z0)`` (1 at no load, 0 where the stiffness is held at
    its maximum). What a filter's tyres need to follow the axle loads
    (``estimator.tyre_load_sensitivity_front``, ``_rear``, :mod:`estimation.process_model`
    (D3''))."""
    ratio = max(load_n, 0.0) / (params.cornering_stiffness_peak_load_ratio
                                * params.nominal_load_n)
    return (1.0 - ratio * ratio) / (1.0 + ratio * ratio) if ratio < 1.0 else 0.0


def _magic_formula(slip: float, stiffness: float, shape: float, curvature: float,
                   peak: float) -> float:
    """``D sin(C atan(B s - E (B s - atan(B s))))`` with ``B = K / (C D)`` (4.E9, 4.E19)."""
    bs = stiffness / (shape * peak) * slip
    return peak * math.sin(shape * math.atan(bs - curvature * (bs - math.atan(bs))))


MIN_PEAK_FRICTION_FACTOR = 0.1
"""Lowest ``1 + p_D2 df_z`` (a steep slope at a large load must not make the peak vanish)."""


def peak_force_n(params: TyreParams, load_n: float, friction: float) -> float:
    """``mu (1 + p_D2 df_z) F_z`` (4.E13, 4.E23) with ``mu = friction`` [N]: the peak in a
    direction whose friction (``tyre_friction`` times that direction's scale) is given."""
    dfz = (load_n - params.nominal_load_n) / params.nominal_load_n
    factor = max(1.0 + params.peak_friction_load_slope * dfz, MIN_PEAK_FRICTION_FACTOR)
    return friction * load_n * factor


def peak_forces_n(params: TyreParams, load_n: float, friction: float) -> tuple[float, float]:
    """``(D_x, D_y)``: the longitudinal and lateral peak forces, ``friction`` scaled by
    ``lambda_mux`` and ``lambda_muy`` (4.E13, 4.E23) [N]."""
    return (peak_force_n(params, load_n, friction * params.longitudinal_friction_scale),
            peak_force_n(params, load_n, friction * params.lateral_friction_scale))


def pure_longitudinal_force_n(params: TyreParams, slip_ratio: float, load_n: float,
                              friction: float) -> float:
    """``F_x0``: longitudinal force at slip ratio ``k`` and no slip angle (4.E9) [N]."""
    if load_n < MIN_LOAD_N:
        return 0.0
    return _magic_formula(
        slip_ratio,
        slip_stiffness_n(params, load_n),
        params.longitudinal_shape,
        params.longitudinal_curvature,
        peak_force_n(params, load_n, friction * params.longitudinal_friction_scale),
    )


def pure_lateral_force_n(params: TyreParams, tan_slip_angle: float, load_n: float,
                         friction: float) -> float:
    """``F_y0``: lateral force at slip angle ``atan(tan_slip_angle)``, no slip ratio (4.E19) [N]."""
    if load_n < MIN_LOAD_N:
        return 0.0
    return _magic_formula(
        tan_slip_angle,
        cornering_stiffness_nprad(params, load_n),
        params.lateral_shape,
        params.lateral_curvature,
        peak_force_n(params, load_n, friction * params.lateral_friction_scale),
    )


def combined_weights(params: TyreParams, slip_ratio: float,
                     tan_slip_angle: float) -> tuple[float, float]:
    """MF weighting functions ``(G_xa, G_yk)`` (4.E50-4.E67), each in [0, 1].

    ``G_xa = cos(r_Cx1 atan(B_xa a))``, ``B_xa = r_Bx1 cos(atan(r_Bx2 k))`` scales the
    longitudinal force down with slip angle; ``G_yk`` likewise the lateral force with slip
    ratio. Both are clipped at zero (the cosine would turn negative at slips far beyond the
    fitted range, for instance a patch sliding sideways at standstill).
    """
    # cos(atan(x)) = 1 / sqrt(1 + x^2)
    decay_x = params.combined_x_stiffness_decay * slip_ratio
    b_xa = params.combined_x_stiffness / math.sqrt(1.0 + decay_x * decay_x)
    g_xa = math.cos(params.combined_x_shape * math.atan(b_xa * tan_slip_angle))
    decay_y = params.combined_y_stiffness_decay * tan_slip_angle
    b_yk = params.combined_y_stiffness / math.sqrt(1.0 + decay_y * decay_y)
    g_yk = math.cos(params.combined_y_shape * math.atan(b_yk * slip_ratio))
    return max(g_xa, 0.0), max(g_yk, 0.0)


def combined_forces_n(params: TyreParams, slip_ratio: float, tan_slip_angle: float,
                      load_n: float, friction: float) -> tuple[float, float]:
    """Steady-state ``(F_x, F_y)`` at combined slip [N], within the friction ellipse of the
    peaks ``(D_x, D_y)`` (the circle ``mu F_z`` with isotropic friction).

    ``F_x = G_xa F_x0``, ``F_y = G_yk F_y0`` (4.E50, 4.E58), then scaled onto the ellipse if
    outside it.
    """
    if load_n < MIN_LOAD_N:
        return 0.0, 0.0
    g_xa, g_yk = combined_weights(params, slip_ratio, tan_slip_angle)
    force_x = g_xa * pure_longitudinal_force_n(params, slip_ratio, load_n, friction)
    force_y = g_yk * pure_lateral_force_n(params, tan_slip_angle, load_n, friction)
    return _onto_friction_ellipse(force_x, force_y, friction_aspect(params),
                                  peak_forces_n(params, load_n, friction)[1])


def friction_aspect(params: TyreParams) -> float:
    """``lambda_muy / lambda_mux``: the longitudinal force times this is measured against
    the lateral peak (exactly 1 with isotropic friction)."""
    return params.lateral_friction_scale / params.longitudinal_friction_scale


def _onto_friction_ellipse(force_x: float, force_y: float, aspect: float,
                           limit_y_n: float) -> tuple[float, float]:
    """Scale ``(force_x, force_y)`` down onto the ellipse of half-axes ``limit_y_n / aspect``
    (longitudinal) and ``limit_y_n`` (lateral) if outside it: ``(aspect F_x)^2 + F_y^2 <=
    D_y^2``, the same as ``(F_x / D_x)^2 + (F_y / D_y)^2 <= 1``."""
    scaled_x = force_x * aspect
    magnitude2 = scaled_x * scaled_x + force_y * force_y
    if magnitude2 > limit_y_n * limit_y_n:
        scale = limit_y_n / math.sqrt(magnitude2)
        return force_x * scale, force_y * scale
    return force_x, force_y


def low_speed_fade(speed_mps: float, fade_speed_mps: float) -> float:
    """``(1 + cos(pi |V| / V_low)) / 2`` below ``V_low``, zero above: 1 at standstill."""
    speed = abs(speed_mps)
    if speed >= fade_speed_mps:
        return 0.0
    return 0.5 * (1.0 + math.cos(math.pi * speed / fade_speed_mps))


def relaxation_lengths_m(params: TyreParams, load_n: float) -> tuple[float, float]:
    """Relaxation lengths ``(sigma_k, sigma_a) = (K_xk / c_x, K_ya / c_y)`` at small slip [m]."""
    return (
        slip_stiffness_n(params, load_n) / params.longitudinal_carcass_stiffness_npm,
        cornering_stiffness_nprad(params, load_n) / params.lateral_carcass_stiffness_npm,
    )


def relax_deflection(deflection_m: Any, slip_velocity_mps: Any, secant_n: Any,
                     stiffness_npm: float, damping_nspm: Any, speed_mps: Any, dt_s: float,
                     exp: Callable[[Any], Any] = math.exp) -> tuple[Any, Any]:
    """Exact step of ``de/dt = -(c v* e + f V_s) / (d v* + f)`` over ``dt_s`` for fixed
    ``f`` and ``V_s``; returns the new deflection and its rate at the end of the step.

    Arithmetic and ``exp`` only, so it takes floats or, with ``exp=casadi.exp``, CasADi
    symbols (:mod:`cosim.plant.tyre_patches`)."""
    denominator = damping_nspm * speed_mps + secant_n
    rate_coefficient = stiffness_npm * speed_mps / denominator
    forcing = secant_n * slip_velocity_mps / denominator
    steady = -forcing / rate_coefficient
    deflection = steady + (deflection_m - steady) * exp(-rate_coefficient * dt_s)
    return deflection, -(rate_coefficient * deflection + forcing)


def patch_step(params: TyreParams, friction: float, load_n: float, forward_speed_mps: float,
               slip_velocity_x_mps: float, slip_velocity_y_mps: float, state: PatchState,
               dt_s: float) -> PatchForces:
    """Advance one tyre's carcass by ``dt_s`` and return the forces on the wheel [N].

    Inputs, in the wheel's heading frame at the contact (ISO 8855 axes): ``load_n`` the
    normal load, ``forward_speed_mps`` the wheel centre's forward speed ``V_cx``, and the
    slip velocity ``(V_sx, V_sy)`` of the wheel's material point at the contact. The
    returned forces act on the wheel at the contact point along the heading frame's x and y
    axes, within the friction ellipse of the peaks ``(D_x, D_y)`` (``mu F_z`` with isotropic
    friction). With no load the carcass unloads (state at
    rest, no force). See the module docstring for the equations.
    """
    if load_n < MIN_LOAD_N:
        return PatchForces(0.0, 0.0, PATCH_AT_REST)
    speed = math.sqrt(forward_speed_mps * forward_speed_mps + params.slip_speed_floor_mps**2)
    # The patch's own slip (the wheel's slip velocity plus the carcass's deflection rate of
    # the previous step) sets the secant slopes f = F_ss(s) / s of the characteristic
    # (Rill's "global derivative"); at zero slip, the slope there.
    slip_ratio = -(slip_velocity_x_mps + state.deflection_rate_x_mps) / speed
    tan_slip_angle = -(slip_velocity_y_mps + state.deflection_rate_y_mps) / speed
    limit_x_n, limit_y_n = peak_forces_n(params, load_n, friction)
    g_xa, g_yk = combined_weights(params, slip_ratio, tan_slip_angle)
    stiffness_x = slip_stiffness_n(params, load_n)
    stiffness_y = cornering_stiffness_nprad(params, load_n)
    if abs(slip_ratio) > SLIP_EPSILON:
        secant_x = g_xa * _magic_formula(
            slip_ratio, stiffness_x, params.longitudinal_shape,
            params.longitudinal_curvature, limit_x_n,
        ) / slip_ratio
    else:
        secant_x = g_xa * stiffness_x
    if abs(tan_slip_angle) > SLIP_EPSILON:
        secant_y = g_yk * _magic_formula(
            tan_slip_angle, stiffness_y, params.lateral_shape, params.lateral_curvature,
            limit_y_n,
        ) / tan_slip_angle
    else:
        secant_y = g_yk * stiffness_y
    fade = low_speed_fade(forward_speed_mps, params.low_speed_damping_fade_mps)
    damping_x = (
        params.longitudinal_carcass_damping_nspm
        + fade * params.low_speed_longitudinal_damping_nspm
    )
    damping_y = params.lateral_carcass_damping_nspm + fade * params.low_speed_lateral_damping_nspm
    stiffness_cx = params.longitudinal_carcass_stiffness_npm
    stiffness_cy = params.lateral_carcass_stiffness_npm
    deflection_x, rate_x = relax_deflection(
        state.deflection_x_m, slip_velocity_x_mps, secant_x, stiffness_cx, damping_x, speed,
        dt_s,
    )
    deflection_y, rate_y = relax_deflection(
        state.deflection_y_m, slip_velocity_y_mps, secant_y, stiffness_cy, damping_y, speed,
        dt_s,
    )
    force_x, force_y = _onto_friction_ellipse(
        stiffness_cx * deflection_x + damping_x * rate_x,
        stiffness_cy * deflection_y + damping_y * rate_y,
        friction_aspect(params),
        limit_y_n,
    )
    return PatchForces(force_x, force_y, PatchState(deflection_x, deflection_y, rate_x, rate_y))
