"""The longitudinal slip of a wheel the filter reads for speed, from the forces that brake or
drive it: the wheel-speed model's correction to free rolling.

A wheel turns at ``omega = v_w (1 + kappa) / R``, with ``v_w`` its centre's speed along
its plane and ``kappa`` its longitudinal slip ratio (SAE J670: ``kappa = (omega R - v_w) /
v_w``); below the tyre's force peak the slip is proportional to the longitudinal force,
``kappa = F_x / K_x`` with the slip stiffness ``K_x`` about proportional to the load
``F_z`` (the Magic Formula's ``K_xk = p_Kx1 F_z`` at nominal load; Pacejka, "Tyre and
Vehicle Dynamics", 3rd ed., 2012, eq. 4.E15). So::

    kappa = c F_x sqrt(1 + (B alpha)^2) / F_z,   c = 1 / p_Kx1                     (S1)

``c`` is the estimator's belief ``wheel_slip_per_force_ratio`` (0: the wheels roll freely).
A tyre that slips sideways as well gives less longitudinal force for a slip: the Magic
Formula's combined-slip weight ``G_xa = cos(C_xa atan(B_xa alpha))`` (Pacejka 2012, eq.
4.E54-4.E56; with ``C_xa = r_Cx1 = 1`` and ``B_xa = r_Bx1`` at small ``kappa``, ``G_xa =
1 / sqrt(1 + (B alpha)^2)``), so the slip of a given force grows by ``1 / G_xa`` with the
wheel's slip angle ``alpha``; ``B`` is ``wheel_slip_combined_stiffness_1prad`` (12.35, the
sedan's tyre's ``r_Bx1``). On the ring's plant tyres the front wheels' slip over ``c F_x /
F_z`` was 1.05, 1.22 and 1.51 at slip angles 0.02-0.04, 0.04-0.07 and 0.07-0.2 rad, where
``1 / G_xa`` is 1.06, 1.25 and 1.34.
Near the tyre's force peak the slip grows faster than the force: the Magic Formula's pure
longitudinal curve (Pacejka 2012, eq. 4.E9-4.E13) with shape ``C``, curvature ``E`` and
peak ``D = mu F_z`` (``mu``: the tyre's peak force per load),
``F_x0 = D sin(C atan(B k - E (B k - atan(B k))))`` with ``B = K_x / (C D)``, inverted::

    rho = F_x0 / (mu F_z),   phi = tan(asin(rho) / C),
    (1 - E) x + E atan(x) = phi,   kappa = x / B = x c C mu                      (S1')

(``x`` found by three Newton steps from ``phi``; ``rho`` held within +-0.95, where the
curve is nearly flat), with ``F_x0 = F_x sqrt(1 + (B alpha)^2)`` the force the tyre would
give without its slip angle. For small forces ``x = phi = rho / C`` and (S1') is (S1); at
60-90 % of the peak it slips 1.1-1.5 times (S1)'s: the 1.2 t Ford Escort's light rear
wheels launching at 3 m/s^2 (``F_x / F_z`` 0.75) slipped 4.5 % where (S1) says 3.5 % and
(S1') 4.2 %. ``C``, ``E`` and ``mu`` are the estimator's beliefs
``wheel_slip_shape``, ``wheel_slip_curvature`` and ``wheel_slip_peak_force_ratio`` (the
sedan's tyre's ``p_Cx1`` 1.685, ``p_Ex1`` 0.344 and peak 1.0; a very large peak gives
(S1)).
A free-rolling wheel slips under the brakes only: the brake torque splits over the axles
with a fixed balance, the front share ``b`` (:attr:`CarParams.brake_front_share`), and each
wheel's tyre force also turns the wheel's own inertia::

    F_total = m_e a_x + 1/2 rho C_d A v|v| + C_rr m g tanh(v / 0.1) + F_yf sin(delta)   (S2)
    F_x = b_i min(F_total, 0) + d_i max(F_total, 0) + (I_w / R^2) a_x    (S3)
    F_z = m (g l_o / L -+ a_x h / L) / 2 -+ m r v_x h l_o / (L t)        (S4)

with ``m_e = m + 4 I_w / R^2`` (the low-level layer's model of what the tyres must deliver,
:mod:`cosim.plant.low_level`) and ``F_yf sin(delta)`` the part of the front tyres' lateral
force ``F_yf`` that acts along the car when they are steered by ``delta``: a cornering drag
that slows the car without a brake torque (the longitudinal forces the wheels deliver,
summed in the vehicle frame, are ``m_e a_x`` plus the road loads plus it), so in a turn the
brakes slow the car less than ``a_x`` says and the wheels slip less. ``b_i`` is the wheel's
brake share (``b / 2`` at the front, ``(1 - b) / 2`` at the rear), ``d_i`` its drive share
(the driven wheels split the drive torque equally: an all-wheel drive's wheels, which the
filter reads too), ``l_o`` the other axle's distance to the CoG and the load moving to the
front axle as the car brakes (``-`` at the front, ``+`` at the rear) and to the outer wheels
as it turns (``-`` on the inner wheel; the lateral acceleration ``r v_x`` of a steady turn,
shared by the axles as their static loads, ``t`` the axle's track): the brakes pull the
wheels of an axle alike, so the inner, lighter one slips more.

On the sedan the front wheels slip about 1 % when it brakes at 2 m/s^2: at 20 m/s that is
0.2 m/s, where the wheel speeds' noise is 0.016 m/s; braking at 1.3 m/s^2 in a turn at
2.7 m/s^2, the inner front wheel some 0.35 % more than the outer one. Without (S1)-(S4) the
filter gated the front wheels in every braking zone of the circuit.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca

from cosim.core.physical_constants import AIR_DENSITY_KGPM3, GRAVITY_MPS2
from cosim.core.vehicle_params import VehicleParams

ROLLING_SPEED_SCALE_MPS = 0.1
"""Speed over which rolling resistance fades in (as the plant applies it) [m/s]."""

LINEAR_PEAK_FORCE_RATIO = 1e3
"""A peak force per load so far above any force that (S1') is (S1) (to 1e-6 of the slip
at a force as large as the load): the peak of a :class:`WheelLoads` without one."""

MAX_PEAK_SHARE = 0.95
"""(S1')'s ``rho`` is held within this share of the peak."""

NEWTON_STEPS = 3
"""Newton steps of (S1')'s ``x`` (from ``phi``: the residual is below 1e-9 of ``phi`` for
``E`` up to 0.5 and ``rho`` up to 0.95)."""


@dataclass(frozen=True)
class WheelLoads:
    """The numbers of (S1)-(S4), from the filter's belief of the car (SI)."""

    mass_kg: float
    effective_mass_kg: float
    wheel_inertia_mass_kg: float
    """``I_w / R^2`` of one wheel [kg]."""
    drag_coefficient: float
    """``1/2 rho C_d A`` [kg/m]."""
    rolling_force_n: float
    brake_front_share: float
    front_drive_share: float
    """Each front wheel's share of the drive force (0 for a rear-wheel drive)."""
    rear_drive_share: float
    cog_front_m: float
    cog_rear_m: float
    cog_height_m: float
    slip_per_force_ratio: float
    """``c`` of (S1): slip ratio per unit of ``F_x / F_z``."""
    combined_stiffness: float = 0.0
    """``B`` of (S1): the combined-slip weight's stiffness (0: none) [1/rad]."""
    peak_force_ratio: float = LINEAR_PEAK_FORCE_RATIO
    """``mu`` of (S1'): the tyre's peak longitudinal force per load."""
    shape: float = 1.0
    """``C`` of (S1')."""
    curvature: float = 0.0
    """``E`` of (S1')."""
    vertical_compliance_mpn: float = 0.0
    """The tyre's loaded radius drop per newton of its vertical load, ``1 / k_z`` [m/N]:
    the rolling radius ``R s - F_z / k_z`` (0: the rolling radius does not move with load)."""

    @classmethod
    def from_vehicle(cls, belief: VehicleParams, slip_per_force_ratio: float,
                     combined_stiffness: float = 0.0,
                     saturation: tuple[float, float, float] | None = None,
                     vertical_compliance_mpn: float = 0.0) -> WheelLoads:
        """The numbers of ``belief``; ``saturation`` is (S1')'s ``(mu, C, E)`` (None: the
        linear law (S1))."""
        peak, shape, curvature = (LINEAR_PEAK_FORCE_RATIO, 1.0, 0.0) if saturation is None \
            else saturation
        inertia_mass = belief.wheel_inertia_kgm2 / belief.wheel_radius_m**2
        front_drive = {"rwd": 0.0, "fwd": 0.5, "awd": 0.25}[belief.drive]
        rear_drive = {"rwd": 0.5, "fwd": 0.0, "awd": 0.25}[belief.drive]
        return cls(
            mass_kg=belief.mass_kg,
            effective_mass_kg=belief.mass_kg + 4.0 * inertia_mass,
            wheel_inertia_mass_kg=inertia_mass,
            drag_coefficient=0.5 * AIR_DENSITY_KGPM3 * belief.drag_area_m2,
            rolling_force_n=belief.rolling_resistance * belief.mass_kg * GRAVITY_MPS2,
            brake_front_share=belief.brake_front_share,
            front_drive_share=front_drive,
            rear_drive_share=rear_drive,
            cog_front_m=belief.cog_front_m,
            cog_rear_m=belief.cog_rear_m,
            cog_height_m=belief.cog_height_m,
            slip_per_force_ratio=slip_per_force_ratio,
            combined_stiffness=combined_stiffness,
            peak_force_ratio=peak,
            shape=shape,
            curvature=curvature,
            vertical_compliance_mpn=vertical_compliance_mpn,
        )


def slip_ratio(s: Mapping[str, ca.SX], front: bool, load_n: ca.SX, loads: WheelLoads,
               cornering_drag_n: ca.SX | float = 0.0, slip_angle_rad: ca.SX | float = 0.0,
               saturating: bool = False) -> ca.SX:
    """``kappa`` of a wheel (front or rear) carrying ``load_n`` (:func:`wheel_load`, (S4)),
    (S1)-(S3), from the state's speed and longitudinal acceleration;
    ``cornering_drag_n`` is ``F_yf sin(delta)`` of (S2) [N], ``slip_angle_rad`` the wheel's
    ``alpha`` of (S1); ``saturating``: (S1') instead of (S1)."""
    vx, ax = s["vx_mps"], s["ax_mps2"]
    total = (loads.effective_mass_kg * ax + loads.drag_coefficient * vx * ca.fabs(vx)
             + loads.rolling_force_n * ca.tanh(vx / ROLLING_SPEED_SCALE_MPS)
             + cornering_drag_n)
    if front:
        brake, drive = 0.5 * loads.brake_front_share, loads.front_drive_share
    else:
        brake, drive = 0.5 * (1.0 - loads.brake_front_share), loads.rear_drive_share
    force = (brake * ca.fmin(total, 0.0) + drive * ca.fmax(total, 0.0)
             + loads.wheel_inertia_mass_kg * ax)
    combined = ca.sqrt(1.0 + (loads.combined_stiffness * slip_angle_rad) ** 2)
    ratio = force * combined / load_n
    return slip_of_force_ratio(ratio, loads) if saturating else \
        loads.slip_per_force_ratio * ratio


def wheel_load(s: Mapping[str, ca.SX], front: bool, left: bool, track_m: ca.SX,
               loads: WheelLoads) -> ca.SX:
    """The wheel's vertical load [N]: its axle's static share with the longitudinal load
    transfer of ``a_x`` and the lateral one of ``r v_x`` on an axle of track ``track_m``,
    (S4)."""
    vx, ax = s["vx_mps"], s["ax_mps2"]
    wheelbase = loads.cog_front_m + loads.cog_rear_m
    lever = loads.cog_rear_m if front else loads.cog_front_m
    pitch = (-1.0 if front else 1.0) * ax * loads.cog_height_m
    roll = (1.0 if left else -1.0) * -s["yaw_rate_radps"] * vx * loads.cog_height_m * lever
    return loads.mass_kg * (0.5 * (GRAVITY_MPS2 * lever + pitch) + roll / track_m) / wheelbase


def slip_of_force_ratio(ratio: ca.SX, loads: WheelLoads) -> ca.SX:
    """(S1'): the slip ratio ``kappa`` at which the tyre gives ``ratio = F_x0 / F_z``."""
    peak, shape, curvature = loads.peak_force_ratio, loads.shape, loads.curvature
    rho = ca.fmin(ca.fmax(ratio / peak, -MAX_PEAK_SHARE), MAX_PEAK_SHARE)
    phi = ca.tan(ca.asin(rho) / shape)
    x = phi
    for _ in range(NEWTON_STEPS):
        x = x - ((1.0 - curvature) * x + curvature * ca.atan(x) - phi) / (
            1.0 - curvature + curvature / (1.0 + x * x))
    return x * loads.slip_per_force_ratio * shape * peak
