"""The four tyres of a physics step in one call: contact geometry in, wheel wrenches out.

:func:`cosim.plant.tyre_model.patch_step` is the plain reference of one tyre, called per
wheel in Python. This module states the same step once more, symbolically (CasADi SX), for
all four wheels together, with the contact geometry of
:class:`cosim.plant.tyre_forces.MagicFormulaTyres` (heading frame at the contact, slip velocity of
the wheel's material point, wheel-centre speed; the force's moment about the wheel's centre
of mass), and builds one CasADi :class:`~casadi.Function` of it: a physics step then costs
one call into CasADi's compiled virtual machine instead of some 400 Python float
operations and four function calls. ``tests/plant/test_tyre_patches.py`` checks it against
the plain reference wheel by wheel.

The branches of the reference become ``if_else`` (both sides are evaluated; divisions in
the side not taken are guarded so they stay finite). Every equation is the reference's:
see :mod:`cosim.plant.tyre_model` for the Magic Formula (Pacejka, *Tyre and Vehicle
Dynamics*, 3rd ed., 2012, §4.3.2) and the relaxing contact patch (Pacejka 2012, ch. 7;
Rill, *Road Vehicle Dynamics*, CRC 2011, ch. 3).

The function reads MuJoCo's arrays whole (``cvel``, ``xpos``, ``xipos``, ``xmat``,
``subtree_com``: the wheel bodies' rows are picked inside it), so they are passed without a
copy; per wheel, its contact (:data:`CONTACT_FIELDS`) and carcass state come in small
buffers. It is compiled to C (:mod:`cosim.core.compiled_function`) when a C compiler is
there; otherwise the plant keeps the plain reference.
"""

from __future__ import annotations

import dataclasses
import functools
import types
from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np

from cosim.core.built_once import built_once
from cosim.core.tyre_params import TyreParams
from cosim.plant.tyre_model import (
    MIN_LOAD_N,
    MIN_PEAK_FRICTION_FACTOR,
    SLIP_EPSILON,
    friction_aspect,
    relax_deflection,
)

CONTACT_FIELDS: tuple[tuple[str, int], ...] = (
    ("in_contact", 1),        # 1 with a ground contact, 0 without (wheel in the air)
    ("contact_pos_m", 3),     # contact point, world frame
    ("normal", 3),            # unit contact normal pointing into the tyre, world frame
    ("load_n", 1),            # normal load: the contact's normal force of the step before
)
"""One wheel's block of the ``contacts`` input, in order."""

CONTACT_SIZE = sum(size for _, size in CONTACT_FIELDS)
PATCH_STATE_SIZE = 4
"""Deflection x, y [m], deflection rate x, y [m/s] (:class:`PatchState` order)."""
FORCE_FIELDS = 6
"""Per wheel in the ``forces`` output: load, V_cx, V_sx, V_sy, F_x, F_y (TyreForces order)."""
INPUT_NAMES = ("cvel", "xpos", "xipos", "xmat", "subtree_com", "contacts", "patch_state",
               "road_tyres")
"""``road_tyres``: the road's friction coefficient, then each wheel's :data:`TYRE_NUMBERS`
(:func:`road_tyre_numbers`): numbers, not constants of the code, so one compiled library
serves every road and every tyre."""
OUTPUT_NAMES = ("wrench", "forces", "new_patch_state")
"""``wrench``: per wheel, its ``xfrc_applied`` row (force, then moment about the centre of
mass); ``new_patch_state``: the new carcass states."""


TYRE_PATCHES = "cosim_tyre_patches"
"""The four tyres' function's name (and its compiled library's)."""

TYRE_NUMBERS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(TyreParams))
"""The numbers of one tyre (:class:`TyreParams`' fields, in order) in ``road_tyres``."""


def road_tyre_numbers(friction: float, params: Sequence[TyreParams]) -> np.ndarray:
    """The ``road_tyres`` input: the road's friction, then each wheel's tyre numbers."""
    return np.array([friction, *(float(getattr(p, name)) for p in params
                                 for name in TYRE_NUMBERS)])


def _symbolic_tyre(numbers: ca.SX) -> Any:
    """A tyre whose every number is a symbol (``numbers[i]`` for ``TYRE_NUMBERS[i]``): the
    equations below read it as they read a :class:`TyreParams`."""
    return types.SimpleNamespace(**{name: numbers[i] for i, name in enumerate(TYRE_NUMBERS)})


def _magic_formula(slip: ca.SX, stiffness: ca.SX, shape: float, curvature: float,
                   peak: ca.SX) -> ca.SX:
    bs = stiffness / (shape * peak) * slip
    return peak * ca.sin(shape * ca.atan(bs - curvature * (bs - ca.atan(bs))))


def _onto_ellipse(force_x: ca.SX, force_y: ca.SX, aspect: float,
                  limit: ca.SX) -> tuple[ca.SX, ca.SX]:
    """The reference's friction-ellipse guard: ``(aspect F_x)^2 + F_y^2 <= D_y^2``."""
    scaled_x = force_x * aspect
    magnitude2 = scaled_x * scaled_x + force_y * force_y
    outside = magnitude2 > limit * limit
    scale = limit / ca.sqrt(ca.if_else(outside, magnitude2, 1.0))
    return ca.if_else(outside, force_x * scale, force_x), ca.if_else(outside, force_y * scale,
                                                                       force_y)


def _secant(slip: ca.SX, weight: ca.SX, stiffness: ca.SX, shape: float, curvature: float,
            limit: ca.SX) -> ca.SX:
    """``G F_ss(s) / s``, or ``G K`` at zero slip (the reference's two branches)."""
    sliding = ca.fabs(slip) > SLIP_EPSILON
    safe_slip = ca.if_else(sliding, slip, 1.0)
    return ca.if_else(sliding,
                      weight * _magic_formula(safe_slip, stiffness, shape, curvature, limit)
                      / safe_slip,
                      weight * stiffness)


def patch_step_sx(params: Any, friction: ca.SX | float, load: ca.SX,
                  forward_speed: ca.SX,
                  slip_x: ca.SX, slip_y: ca.SX, state: Sequence[ca.SX],
                  dt_s: float) -> tuple[ca.SX, ca.SX, list[ca.SX]]:
    """:func:`cosim.plant.tyre_model.patch_step`, symbolically: ``(F_x, F_y, new state)``;
    ``params`` a :class:`TyreParams` or a symbolic one (:func:`_symbolic_tyre`)."""
    p = params
    loaded = load >= MIN_LOAD_N
    safe_load = ca.if_else(loaded, load, p.nominal_load_n)
    speed = ca.sqrt(forward_speed * forward_speed + p.slip_speed_floor_mps**2)
    deflection_x, deflection_y, rate_x, rate_y = state
    slip_ratio = -(slip_x + rate_x) / speed
    tan_slip_angle = -(slip_y + rate_y) / speed
    dfz = (safe_load - p.nominal_load_n) / p.nominal_load_n
    load_factor = ca.fmax(1.0 + p.peak_friction_load_slope * dfz, MIN_PEAK_FRICTION_FACTOR)
    limit_x = friction * p.longitudinal_friction_scale * safe_load * load_factor
    limit_y = friction * p.lateral_friction_scale * safe_load * load_factor
    decay_x = p.combined_x_stiffness_decay * slip_ratio
    b_xa = p.combined_x_stiffness / ca.sqrt(1.0 + decay_x * decay_x)
    g_xa = ca.fmax(ca.cos(p.combined_x_shape * ca.atan(b_xa * tan_slip_angle)), 0.0)
    decay_y = p.combined_y_stiffness_decay * tan_slip_angle
    b_yk = p.combined_y_stiffness / ca.sqrt(1.0 + decay_y * decay_y)
    g_yk = ca.fmax(ca.cos(p.combined_y_shape * ca.atan(b_yk * slip_ratio)), 0.0)
    stiffness_x = (safe_load * (p.slip_stiffness_per_load + p.slip_stiffness_load_slope * dfz)
                   * ca.exp(p.slip_stiffness_load_exponent * dfz))
    ratio = ca.fmin(safe_load / (p.cornering_stiffness_peak_load_ratio * p.nominal_load_n), 1.0)
    stiffness_y = (p.cornering_stiffness_max_prad * p.nominal_load_n * 2.0 * ratio
                   / (1.0 + ratio * ratio))
    secant_x = _secant(slip_ratio, g_xa, stiffness_x, p.longitudinal_shape,
                       p.longitudinal_curvature, limit_x)
    secant_y = _secant(tan_slip_angle, g_yk, stiffness_y, p.lateral_shape,
                       p.lateral_curvature, limit_y)
    abs_speed = ca.fabs(forward_speed)
    fade = ca.if_else(abs_speed >= p.low_speed_damping_fade_mps, 0.0,
                      0.5 * (1.0 + ca.cos(ca.pi * abs_speed / p.low_speed_damping_fade_mps)))
    damping_x = (p.longitudinal_carcass_damping_nspm
                 + fade * p.low_speed_longitudinal_damping_nspm)
    damping_y = p.lateral_carcass_damping_nspm + fade * p.low_speed_lateral_damping_nspm
    cx, cy = p.longitudinal_carcass_stiffness_npm, p.lateral_carcass_stiffness_npm
    new_x, new_rate_x = relax_deflection(deflection_x, slip_x, secant_x, cx, damping_x, speed,
                                         dt_s, ca.exp)
    new_y, new_rate_y = relax_deflection(deflection_y, slip_y, secant_y, cy, damping_y, speed,
                                         dt_s, ca.exp)
    force_x, force_y = _onto_ellipse(cx * new_x + damping_x * new_rate_x,
                                     cy * new_y + damping_y * new_rate_y,
                                     friction_aspect(p), limit_y)

    def unless_unloaded(value: ca.SX) -> ca.SX:
        return ca.if_else(loaded, value, 0.0)

    return (unless_unloaded(force_x), unless_unloaded(force_y),
            [unless_unloaded(v) for v in (new_x, new_y, new_rate_x, new_rate_y)])


def _cross(a: Sequence[ca.SX], b: Sequence[ca.SX]) -> list[ca.SX]:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _dot(a: Sequence[ca.SX], b: Sequence[ca.SX]) -> ca.SX:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _wheel(params: Any, friction: ca.SX, dt_s: float, subtree_com: list[ca.SX],
           body: dict[str, list[ca.SX]], contact: dict[str, list[ca.SX]],
           state: list[ca.SX]) -> tuple[list[ca.SX], list[ca.SX], list[ca.SX]]:
    """One wheel's wrench, forces and new carcass state."""
    normal = contact["normal"]
    axis = [body["xmat"][1], body["xmat"][4], body["xmat"][7]]  # body y in the world
    heading = _cross(axis, normal)  # spin axis x normal: the heading in the road plane
    norm = ca.sqrt(_dot(heading, heading))
    heading = [h / norm for h in heading]
    lateral = _cross(normal, heading)
    angular, linear = body["cvel"][:3], body["cvel"][3:]

    def velocity_at(point: list[ca.SX]) -> list[ca.SX]:
        # MuJoCo's cvel is the velocity at the subtree's CoM: v + w x (p - c).
        arm = [point[i] - subtree_com[i] for i in range(3)]
        turn = _cross(angular, arm)
        return [linear[i] + turn[i] for i in range(3)]

    position = contact["contact_pos_m"]
    material = velocity_at(position)
    forward_speed = _dot(velocity_at(body["xpos"]), heading)
    slip_x, slip_y = _dot(material, heading), _dot(material, lateral)
    load = contact["load_n"][0]
    force_x, force_y, new_state = patch_step_sx(params, friction, load, forward_speed,
                                                slip_x, slip_y, state, dt_s)
    force = [force_x * heading[i] + force_y * lateral[i] for i in range(3)]
    arm = [position[i] - body["xipos"][i] for i in range(3)]
    on = contact["in_contact"][0] > 0.5

    def when_on(values: list[ca.SX]) -> list[ca.SX]:
        return [ca.if_else(on, value, 0.0) for value in values]

    return (when_on([*force, *_cross(arm, force)]),
            when_on([load, forward_speed, slip_x, slip_y, force_x, force_y]),
            when_on(new_state))


@functools.lru_cache(maxsize=4)
def _wheel_function(dt_s: float) -> ca.Function:
    """:func:`_wheel` as a CasADi function of one wheel's tyre numbers, the road's friction,
    the subtree's centre of mass, the wheel body's ``cvel``, ``xpos``, ``xipos`` and
    ``xmat``, its contact (:data:`CONTACT_FIELDS`) and carcass state: the equations are
    written in Python once, and each wheel's call expands into the same operations
    (some 13 ms of a process's set-up)."""
    numbers = ca.SX.sym("tyre", len(TYRE_NUMBERS))
    friction = ca.SX.sym("friction")
    subtree_com = ca.SX.sym("subtree_com", 3)
    body = {name: ca.SX.sym(name, width)
            for name, width in (("cvel", 6), ("xpos", 3), ("xipos", 3), ("xmat", 9))}
    contact = ca.SX.sym("contact", CONTACT_SIZE)
    state = ca.SX.sym("patch_state", PATCH_STATE_SIZE)
    fields, offset = {}, 0
    for name, size in CONTACT_FIELDS:
        fields[name] = [contact[offset + j] for j in range(size)]
        offset += size
    wrench, force, new_state = _wheel(
        _symbolic_tyre(numbers), friction, dt_s, [subtree_com[i] for i in range(3)],
        {name: [value[i] for i in range(value.numel())] for name, value in body.items()},
        fields, [state[i] for i in range(PATCH_STATE_SIZE)])
    return ca.Function("cosim_tyre_wheel",
                       [numbers, friction, subtree_com, *body.values(), contact, state],
                       [ca.vertcat(*wrench), ca.vertcat(*force), ca.vertcat(*new_state)])


def tyre_patches_function(dt_s: float, wheel_bodies: Sequence[int], root_body: int,
                          n_bodies: int) -> ca.Function:
    """:func:`_tyre_patches_function`, built once per process for the same structure."""
    return _tyre_patches_function(float(dt_s), tuple(int(b) for b in wheel_bodies),
                                  int(root_body), int(n_bodies))


@built_once
def _tyre_patches_function(dt_s: float, wheel_bodies: tuple[int, ...], root_body: int,
                           n_bodies: int) -> ca.Function:
    """``f(cvel, xpos, xipos, xmat, subtree_com, contacts, patch_state, road_tyres) ->
    (wrench, forces, patch_state)`` for the wheels ``wheel_bodies`` (body ids) of a model
    with ``n_bodies`` bodies (see the module docstring). The road's friction coefficient
    (``plant.tyre_friction``) and every tyre's numbers (``plant.tyre.*``, per wheel) are
    an input (:func:`road_tyre_numbers`), so one compiled library serves every road and
    tyre of a model with this structure and physics step."""
    n_wheels = len(wheel_bodies)
    widths = {"cvel": 6, "xpos": 3, "xipos": 3, "xmat": 9, "subtree_com": 3}
    arrays = {name: ca.SX.sym(name, n_bodies * width) for name, width in widths.items()}
    contacts = ca.SX.sym("contacts", n_wheels * CONTACT_SIZE)
    states = ca.SX.sym("patch_state", n_wheels * PATCH_STATE_SIZE)
    road_tyres = ca.SX.sym("road_tyres", 1 + n_wheels * len(TYRE_NUMBERS))
    friction = road_tyres[0]

    def row(name: str, body_id: int) -> list[ca.SX]:
        width = widths[name]
        return [arrays[name][body_id * width + j] for j in range(width)]

    wheel_function = _wheel_function(dt_s)
    wrenches, forces, new_states = [], [], []
    for wheel, body_id in enumerate(wheel_bodies):
        first = 1 + wheel * len(TYRE_NUMBERS)
        body = [ca.vertcat(*row(name, body_id)) for name in ("cvel", "xpos", "xipos", "xmat")]
        wrench, force, new_state = wheel_function(
            road_tyres[first:first + len(TYRE_NUMBERS)], friction,
            ca.vertcat(*row("subtree_com", root_body)), *body,
            contacts[wheel * CONTACT_SIZE:(wheel + 1) * CONTACT_SIZE],
            states[wheel * PATCH_STATE_SIZE:(wheel + 1) * PATCH_STATE_SIZE])
        wrenches.append(wrench)
        forces.append(force)
        new_states.append(new_state)
    return ca.Function(
        TYRE_PATCHES,
        [*arrays.values(), contacts, states, road_tyres],
        [ca.vertcat(*wrenches), ca.vertcat(*forces), ca.vertcat(*new_states)],
        list(INPUT_NAMES), list(OUTPUT_NAMES),
    )
