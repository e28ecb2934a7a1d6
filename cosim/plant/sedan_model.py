"""The sedan's MuJoCo model: the nominal car in ``models/sedan.xml``, variants made in code.

``models/sedan.xml`` is the sedan of The MathWorks' lane-keeping MPC example
(m = 1575 kg, I_z = 2875 kg m^2, l_f = 1.2 m, l_r = 1.6 m; see ``models/README.md``).
:func:`build_sedan` loads it with dm_control's PyMJCF and edits the tree for any
:class:`~cosim.core.vehicle_params.PlantConfig` (the pattern of dm_control's ``suite/cartpole.py``
beside ``cartpole.xml``): XML is never copied to make a variant. :func:`sedan_layout` derives every
number the XML holds (chassis mass and inertia so that the *total* car has the configured mass, CoG
and yaw inertia; suspension springs for the configured ride frequencies at the static corner loads;
steering limits), so the nominal XML and a variant built from the nominal config agree (tests/plant
checks this).

Model structure (all names are fixed; the plant looks everything up by name)::

    world
      ground (plane geom), sun (light)
      chassis (body, free joint chassis_free; frame origin = nominal CoG, ISO 8855 axes)
        imu (site at the CoG), chase (camera), chassis_shell / chassis_cabin (visual geoms)
        <wheel>_wheel (body) for wheel in front_left, front_right, rear_left, rear_right
          <wheel>_suspension  slide joint along chassis z, spring + damper
          <wheel>_steer       hinge about z (front wheels only), position servo
          <wheel>_spin        hinge about y, positive when rolling forward
          <wheel>_tyre        sphere: the only colliding geom of the car (condim 1 with
                              the Magic Formula tyres, 3 with MuJoCo's contact friction)
          <wheel>_rim         visual cylinder
      car_<name>/ (traffic: one mocap copy of models/traffic_car.xml per car, cosim.plant.traffic)
    actuators: <front wheel>_steer_servo, <driven wheel>_drive (motor on the spin joint)

The joints of one wheel body compose in order (MuJoCo applies them as a chain), so the spin
axis turns with the steer angle.
"""

from __future__ import annotations

import base64
import importlib.resources
import math
import types
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from cosim.core.built_on_disk import kept_on_disk
from cosim.core.built_once import built_once
from cosim.core.exceptions import ConfigError
from cosim.core.records import WHEEL_NAMES
from cosim.core.suspension_params import SuspensionParams
from cosim.core.vehicle_params import CarParams, PlantConfig
from cosim.plant.headless import headless_gl
from cosim.plant.traffic import attach_traffic

if TYPE_CHECKING:
    from dm_control import mjcf

GRAVITY_MPS2 = 9.81
"""MuJoCo's default gravity, used for the static loads [m/s^2]."""

TYRE_WIDTH_M = 0.205
"""Section width of a mid-size sedan tyre (205/55 R16) [m]; sets the wheel's
diametral inertia and its visual width."""

STEER_SERVO_FREQUENCY_RADPS = 100.0
"""Natural frequency of the steering position servo [rad/s]. The servo only has to move a
wheel about its steer axis; the steering actuator's lag and rate limit are modelled in the
plant, so the servo is made fast (and critically damped) to stay out of their way."""

GROUND_CLEARANCE_M = 0.15
"""Height of the underbody above the ground (visual only) [m]."""

OVERHANG_M = 0.95
"""Body overhang ahead of the front axle and behind the rear axle (visual only) [m]."""

WHEEL_SIDES: tuple[tuple[str, int, int], ...] = (
    ("front_left", +1, +1),
    ("front_right", +1, -1),
    ("rear_left", -1, +1),
    ("rear_right", -1, -1),
)
"""(wheel, axle sign: +1 front / -1 rear, side sign: +1 left / -1 right), in WHEEL_NAMES
order."""

FRONT_WHEELS: tuple[str, ...] = ("front_left", "front_right")
REAR_WHEELS: tuple[str, ...] = ("rear_left", "rear_right")


def driven_wheels(drive: str) -> tuple[str, ...]:
    """The wheels that receive drive torque for a drive layout ('rwd', 'fwd' or 'awd')."""
    if drive == "rwd":
        return REAR_WHEELS
    if drive == "fwd":
        return FRONT_WHEELS
    if drive == "awd":
        return WHEEL_NAMES
    raise ConfigError(f"drive = {drive!r}: expected one of 'rwd', 'fwd', 'awd'")


def tyre_contact_dimension(tyre_model: str) -> int:
    """``condim`` of the tyre-ground contacts for ``PlantConfig.tyre_model``.

    ``pacejka``: 1, the contacts carry only the normal force (frictionless) and
    :mod:`cosim.plant.tyre_model` supplies the tyre forces; ``contact``: 3, MuJoCo's friction
    (elliptic cone) is the tyre.
    """
    if tyre_model == "pacejka":
        return 1
    if tyre_model == "contact":
        return 3
    raise ConfigError(f"tyre_model = {tyre_model!r}: expected one of 'pacejka', 'contact'")


def ackermann_angles(steer_rad: float, wheelbase_m: float, track_m: float) -> tuple[float, float]:
    """Left and right road-wheel angles for the bicycle-model angle ``steer_rad``.

    Ackermann geometry: both front wheels point at the turn centre on the rear-axle line,
    ``tan(delta_left) = L tan(delta) / (L - t/2 tan(delta))`` and
    ``tan(delta_right) = L tan(delta) / (L + t/2 tan(delta))`` (Gillespie ch. 6, the
    Ackermann angle written for the inner and outer wheel). Positive angles steer left;
    the inner wheel steers more. Valid while ``|tan(delta)| < 2 L / t`` (about 74 deg for
    the sedan).
    """
    tan_delta = math.tan(steer_rad)
    lever = 0.5 * track_m * tan_delta
    left = math.atan2(wheelbase_m * tan_delta, wheelbase_m - lever)
    right = math.atan2(wheelbase_m * tan_delta, wheelbase_m + lever)
    return left, right


@dataclass(frozen=True)
class SedanLayout:
    """Every number of the MJCF model, derived from a :class:`CarParams`.

    Positions are in the chassis frame, whose origin is the car's nominal centre of gravity
    (ISO 8855 axes: x forward, y left, z up). Per-wheel tuples are in ``WHEEL_NAMES`` order.
    """

    cog_height_m: float
    chassis_mass_kg: float
    chassis_com_m: tuple[float, float, float]
    chassis_inertia_kgm2: tuple[float, float, float]
    """Principal moments of the chassis alone about its own CoM (roll, pitch, yaw)."""
    wheel_pos_m: tuple[tuple[float, float, float], ...]
    wheel_mass_kg: float
    wheel_inertia_kgm2: tuple[float, float, float]
    """Wheel inertia about (x, y = axle, z) through its centre."""
    wheel_radius_m: float
    spring_stiffness_npm: tuple[float, ...]
    spring_ref_m: tuple[float, ...]
    """Spring rest position of each suspension slide joint: the joint sits at 0 under the
    static load (negative: the unloaded spring would push the wheel down this far)."""
    damping_nspm: tuple[float, ...]
    steer_joint_limit_rad: float
    """Joint limit of each steer hinge: the inner wheel's Ackermann angle at
    ``max_steer_rad`` on the front track (the road-wheel limit applies to the bicycle-model
    angle)."""
    steer_servo_kp_nmprad: float
    """Gain of the steering position servo [N m/rad]."""


def sedan_layout(params: CarParams,
                 suspension: SuspensionParams | None = None) -> SedanLayout:
    """Derive chassis mass/inertia, wheel placement and suspension from ``params`` and
    ``suspension`` (``plant.suspension``; default: its defaults).

    The chassis body carries everything but the four wheels. Its CoM is placed so that the
    CoM of the whole car is the frame origin (the configured CoG), and its inertia so that
    the whole car has the configured yaw inertia about the CoG (parallel-axis theorem, per
    axis: I_total = I_chassis + m_c d_c^2 + sum_wheels (I_wheel + m_w d_w^2)). Roll and pitch
    inertia of the whole car are ``suspension.roll_inertia_ratio`` and
    ``pitch_inertia_ratio`` times the yaw inertia. Raises :class:`ConfigError` if the wheels
    alone exceed an inertia.
    """
    if suspension is None:
        suspension = SuspensionParams()
    lf, lr = params.cog_front_m, params.cog_rear_m
    wheelbase = lf + lr
    track_front, track_rear = params.axle_tracks_m
    radius = params.wheel_radius_m
    height = params.cog_height_m
    m_w = params.wheel_mass_kg
    m_c = params.mass_kg - 4.0 * m_w
    wheel_z = radius - height
    wheel_pos = tuple(
        (lf, side * 0.5 * track_front, wheel_z) if axle > 0
        else (-lr, side * 0.5 * track_rear, wheel_z)
        for _, axle, side in WHEEL_SIDES
    )
    # Chassis CoM such that the total CoM is at the origin.
    com = tuple(-m_w * sum(p[k] for p in wheel_pos) / m_c for k in range(3))
    # Wheel: axle inertia as configured; diametral as a solid cylinder of the tyre's width,
    # I_d = I_axle / 2 + m w^2 / 12 (exact for a uniform disc, plausible for a wheel).
    i_axle = params.wheel_inertia_kgm2
    i_diam = 0.5 * i_axle + m_w * TYRE_WIDTH_M**2 / 12.0
    wheel_inertia = (i_diam, i_axle, i_diam)
    totals = (
        suspension.roll_inertia_ratio * params.yaw_inertia_kgm2,
        suspension.pitch_inertia_ratio * params.yaw_inertia_kgm2,
        params.yaw_inertia_kgm2,
    )
    chassis_inertia = []
    for axis, (total, name) in enumerate(zip(totals, ("roll", "pitch", "yaw"), strict=True)):
        others = [k for k in range(3) if k != axis]

        def dist2(p: tuple[float, ...], others: list[int] = others) -> float:
            return sum(p[k] ** 2 for k in others)

        wheels = sum(wheel_inertia[axis] + m_w * dist2(p) for p in wheel_pos)
        own = total - wheels - m_c * dist2(com)
        if own <= 0.0:
            raise ConfigError(
                f"yaw_inertia_kgm2 = {params.yaw_inertia_kgm2}: the car's {name} inertia "
                f"({total:.1f} kg m^2, derived from it) is less than the wheels alone give "
                f"about the CoG ({wheels:.1f} kg m^2); expected a larger yaw inertia or "
                "lighter wheels"
            )
        chassis_inertia.append(own)
    ixx, iyy, izz = chassis_inertia
    if ixx + iyy < izz or iyy + izz < ixx or izz + ixx < iyy:
        raise ConfigError(
            f"yaw_inertia_kgm2 = {params.yaw_inertia_kgm2}: the chassis inertia "
            f"({ixx:.1f}, {iyy:.1f}, {izz:.1f}) kg m^2 violates the triangle inequality"
        )
    # Suspension: the chassis's weight shared by the four springs (moments about the
    # chassis CoM), stiffness from the ride frequency, damping from the damping ratio.
    stiffness, spring_ref, damping = [], [], []
    for _, axle, _side in WHEEL_SIDES:
        lever_other = (lr + com[0]) if axle > 0 else (lf - com[0])
        load_n = m_c * GRAVITY_MPS2 * lever_other / (2.0 * wheelbase)
        sprung_kg = load_n / GRAVITY_MPS2
        freq = (suspension.ride_frequency_front_hz if axle > 0
                else suspension.ride_frequency_rear_hz)
        k = sprung_kg * (2.0 * math.pi * freq) ** 2
        stiffness.append(k)
        spring_ref.append(-load_n / k)
        damping.append(2.0 * suspension.damping_ratio * math.sqrt(k * sprung_kg))
    inner_limit, _ = ackermann_angles(params.max_steer_rad, wheelbase, track_front)
    return SedanLayout(
        cog_height_m=height,
        chassis_mass_kg=m_c,
        chassis_com_m=com,  # type: ignore[arg-type]
        chassis_inertia_kgm2=(ixx, iyy, izz),
        wheel_pos_m=wheel_pos,
        wheel_mass_kg=m_w,
        wheel_inertia_kgm2=wheel_inertia,
        wheel_radius_m=radius,
        spring_stiffness_npm=tuple(stiffness),
        spring_ref_m=tuple(spring_ref),
        damping_nspm=tuple(damping),
        steer_joint_limit_rad=inner_limit,
        steer_servo_kp_nmprad=i_diam * STEER_SERVO_FREQUENCY_RADPS**2,
    )


def models_dir() -> Path:
    """The folder of the MJCF files.

    In an installed wheel, ``models/`` is force-included as ``cosim/models``; in the repo
    (editable install) it is ``models/`` next to the ``cosim/`` package directory.
    """
    packaged = importlib.resources.files("cosim") / "models"
    if packaged.is_dir():
        return Path(str(packaged))
    return Path(__file__).resolve().parents[2] / "models"


def sedan_xml_path() -> Path:
    """Path of the nominal sedan model."""
    return models_dir() / "sedan.xml"


def traffic_car_xml_path() -> Path:
    """Path of the traffic car model (:mod:`cosim.plant.traffic`)."""
    return models_dir() / "traffic_car.xml"


def import_mjcf() -> types.ModuleType:
    """Import dm_control's PyMJCF lazily, silencing only GLFW's headless DISPLAY warning.

    Importing dm_control on a machine without a display makes glfw warn that DISPLAY is
    missing; rendering is not used here, so that one warning is harmless.
    """
    with warnings.catch_warnings(), headless_gl():
        warnings.filterwarnings("ignore", message=r".*DISPLAY.*")
        from dm_control import mjcf

    return mjcf


def build_sedan(config: PlantConfig, physics_dt_s: float,
                traffic: tuple[str, ...] = ()) -> mjcf.RootElement:
    """The sedan for ``config`` as a PyMJCF tree, with physics step ``physics_dt_s``.

    Each name of ``traffic`` adds a traffic car (:func:`cosim.plant.traffic.attach_traffic`).

    Applies mass, yaw inertia, CoG position and height, each axle's track, wheel
    radius/mass/inertia,
    tyre friction and contact dimension (:func:`tyre_contact_dimension`), the steering
    limit (joint range), the drive layout (drive motors exist only on the driven wheels,
    added or removed as needed, with the per-wheel share of the torque limit as their
    control range) and the time step.
    """
    if not (math.isfinite(physics_dt_s) and physics_dt_s > 0.0):
        raise ConfigError(f"physics_dt_s = {physics_dt_s!r}: expected a positive number")
    mjcf = import_mjcf()
    layout = sedan_layout(config, config.suspension)
    root = mjcf.from_path(str(sedan_xml_path()))
    root.option.timestep = physics_dt_s

    chassis = root.find("body", "chassis")
    chassis.pos = [0.0, 0.0, layout.cog_height_m]
    chassis.inertial.mass = layout.chassis_mass_kg
    chassis.inertial.pos = list(layout.chassis_com_m)
    chassis.inertial.diaginertia = list(layout.chassis_inertia_kgm2)
    _shape_body(root, config)

    driven = driven_wheels(config.drive)
    drive_limit_per_wheel = config.max_drive_torque_nm / len(driven)
    for index, (wheel, _axle, _side) in enumerate(WHEEL_SIDES):
        body = root.find("body", f"{wheel}_wheel")
        body.pos = list(layout.wheel_pos_m[index])
        body.inertial.mass = layout.wheel_mass_kg
        body.inertial.diaginertia = list(layout.wheel_inertia_kgm2)
        suspension = root.find("joint", f"{wheel}_suspension")
        suspension.stiffness = layout.spring_stiffness_npm[index]
        suspension.springref = layout.spring_ref_m[index]
        suspension.damping = layout.damping_nspm[index]
        tyre = root.find("geom", f"{wheel}_tyre")
        tyre.size = [layout.wheel_radius_m]
        tyre.friction = [config.tyre_friction, *tyre.friction[1:]]
        tyre.condim = tyre_contact_dimension(config.tyre_model)
        rim = root.find("geom", f"{wheel}_rim")
        rim.size = [layout.wheel_radius_m, 0.5 * TYRE_WIDTH_M]
        if wheel in FRONT_WHEELS:
            limit = layout.steer_joint_limit_rad
            root.find("joint", f"{wheel}_steer").range = [-limit, limit]
            servo = root.find("actuator", f"{wheel}_steer_servo")
            servo.ctrlrange = [-limit, limit]
            servo.kp = layout.steer_servo_kp_nmprad
        drive = root.find("actuator", f"{wheel}_drive")
        if wheel in driven:
            if drive is None:
                drive = root.actuator.add(
                    "motor", name=f"{wheel}_drive", joint=root.find("joint", f"{wheel}_spin")
                )
            drive.ctrlrange = [0.0, drive_limit_per_wheel]
        elif drive is not None:
            drive.remove()
    _add_anti_roll_bars(root, config)
    attach_traffic(root, traffic, lambda: mjcf.from_path(str(traffic_car_xml_path())))
    return root


def _add_anti_roll_bars(root: mjcf.RootElement, config: PlantConfig) -> None:
    """An anti-roll bar per axle with a stiffness: a fixed tendon, length ``q_left -
    q_right`` of the suspension travels, of stiffness ``K / t^2`` (``t`` that axle's track),
    so a roll ``phi = (q_left - q_right) / t`` of the axle stores ``K phi^2 / 2`` (Gillespie
    1992, ch. 8: the bar's roll stiffness in parallel with the springs')."""
    track_front, track_rear = config.axle_tracks_m
    bars = (("front", config.suspension.anti_roll_stiffness_front_nmprad, track_front),
            ("rear", config.suspension.anti_roll_stiffness_rear_nmprad, track_rear))
    for axle, stiffness_nmprad, track_m in bars:
        if stiffness_nmprad <= 0.0:
            continue
        tendon = root.tendon.add("fixed", name=f"{axle}_anti_roll_bar",
                                 stiffness=stiffness_nmprad / track_m**2)
        tendon.add("joint", joint=f"{axle}_left_suspension", coef=1.0)
        tendon.add("joint", joint=f"{axle}_right_suspension", coef=-1.0)


def body_box_m(params: CarParams) -> tuple[float, float, float]:
    """The ego's body box in its vehicle frame: ``(centre ahead of the CoG, half length,
    half width)`` [m], fitted to the wheelbase and the wider track."""
    return (0.5 * (params.cog_front_m - params.cog_rear_m),
            0.5 * params.wheelbase_m + OVERHANG_M, 0.5 * params.widest_track_m + 0.1)


def _shape_body(root: mjcf.RootElement, params: CarParams) -> None:
    """Fit the visual body boxes to the wheelbase and the wider track (no mass: explicit
    inertials)."""
    height = params.cog_height_m
    centre_x, length_half, width_half = body_box_m(params)
    shell = root.find("geom", "chassis_shell")
    shell_bottom, shell_top = GROUND_CLEARANCE_M, GROUND_CLEARANCE_M + 0.65
    shell.pos = [centre_x, 0.0, 0.5 * (shell_bottom + shell_top) - height]
    shell.size = [length_half, width_half, 0.5 * (shell_top - shell_bottom)]
    cabin = root.find("geom", "chassis_cabin")
    cabin_top = shell_top + 0.6
    cabin.pos = [centre_x - 0.2, 0.0, 0.5 * (shell_top + cabin_top) - height]
    cabin.size = [0.5 * params.wheelbase_m, width_half - 0.1, 0.5 * (cabin_top - shell_top)]


def sedan_xml_and_assets(config: PlantConfig, physics_dt_s: float,
                         traffic: tuple[str, ...] = ()) -> tuple[str, dict[str, bytes]]:
    """The MJCF text and its assets exactly as simulated (for MuJoCo and for the run log);
    written once per process for the same car, step and traffic (dm_control's MJCF tree and
    its text, some 20 ms a run)."""
    xml, assets = _sedan_xml_and_assets(config, float(physics_dt_s), tuple(traffic))
    return xml, dict(assets)


@built_once
def _sedan_xml_and_assets(config: PlantConfig, physics_dt_s: float,
                          traffic: tuple[str, ...]) -> tuple[str, dict[str, bytes]]:
    """Read from the cache folder when an earlier process wrote the same text (the same
    arguments, code and dm_control: :mod:`cosim.core.built_on_disk`), so a new process
    neither imports PyMJCF nor builds the tree."""
    kept = kept_on_disk("sedan_mjcf", repr((config, physics_dt_s, traffic)),
                        lambda: _mjcf_text(config, physics_dt_s, traffic),
                        packages=("dm_control.mjcf",), folders=(models_dir(),),
                        valid=_is_mjcf_text)
    return kept["xml"], {name: base64.b64decode(data) for name, data in kept["assets"].items()}


def _is_mjcf_text(value: object) -> bool:
    """Whether ``value`` has :func:`_mjcf_text`'s form (text, and assets in base64)."""
    if not (isinstance(value, dict) and isinstance(value.get("xml"), str)
            and isinstance(value.get("assets"), dict)):
        return False
    try:
        for data in value["assets"].values():
            base64.b64decode(data, validate=True)
    except (TypeError, ValueError):  # binascii.Error is a ValueError
        return False
    return True


def _mjcf_text(config: PlantConfig, physics_dt_s: float,
               traffic: tuple[str, ...]) -> dict[str, object]:
    """:func:`build_sedan`'s tree as MJCF text and its assets (base64), as JSON values."""
    root = build_sedan(config, physics_dt_s, traffic)
    return {"xml": root.to_xml_string(precision=12),
            "assets": {name: base64.b64encode(data).decode("ascii")
                       for name, data in root.get_assets().items()}}
