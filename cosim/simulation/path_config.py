"""The ``path:`` section of a scenario: which path, its shape, and the speed along it.

A path is a kind plus parameters as data (``path.kind: slalom``, ``path.spacing_m: 18``),
built by :func:`cosim.simulation.course.build_course`; the reference speed is part of it
(``path.speed_profile``). Every path starts at the origin heading along +x, where the
``initial:`` section puts the car by default.
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.config_fields import setting

PATH_KINDS: tuple[str, ...] = (
    "double-lane-change", "straight", "iso-lane-change", "circle", "figure-eight", "slalom",
    "s-curve", "track", "generated",
)
"""Values of ``path.kind``."""

SPEED_PROFILES: tuple[str, ...] = ("constant", "friction-limited", "stop-and-go")
"""Values of ``path.speed_profile``."""


@dataclass(frozen=True)
class PathConfig:
    """The reference path and speed."""

    kind: str = setting("double-lane-change", choices=PATH_KINDS)
    stretch: float = setting(1.5, low=0.2, high=10.0, doc="x-scale of Falcone's constants")
    speed_mps: float = setting(20.0, low=0.0, high=80.0,
                               doc="reference speed v_D (the top speed of a profile)")
    length_m: float = setting(600.0, low=10.0, high=1e5, doc="length of an open path")
    radius_m: float = setting(
        40.0, low=2.0, high=1e4,
        doc="circle radius; figure-eight: tightest radius of its lobes; s-curve: arc radius")
    arc_deg: float = setting(90.0, low=1.0, high=180.0, doc="s-curve: angle of each arc")
    approach_m: float = setting(
        50.0, low=0.0, high=1e4,
        doc="straight before the manoeuvre (iso-lane-change, slalom, s-curve)")
    spacing_m: float = setting(18.0, low=2.0, high=200.0, doc="slalom: cone spacing")
    cones: int = setting(8, low=2, high=200, doc="slalom: number of cones")
    amplitude_m: float = setting(1.5, low=0.1, high=50.0,
                                 doc="slalom: the path's lateral offset at each cone")
    vehicle_width_m: float = setting(
        0.0, low=0.0, high=5.0,
        doc="iso-lane-change: width the gates are sized for; 0 = the plant's body width")
    file: str = setting(
        "", doc="track: centre-line CSV (racetrack-database x_m,y_m,w_tr_right_m,w_tr_left_m "
        "or plain x,y); relative to the working directory, else a built-in circuit's name")
    seed: int = setting(
        0, low=0, high=2**31 - 1,
        doc="generated: the circuit generator's seed (tracker.paths.generated_circuit: closed "
        "circuits of 300-3000 m, hairpins down to 12 m radius, chicanes, 6-15 m wide)")
    closed: bool = setting(True, doc="track: the centre line is a closed circuit")
    smoothing: bool = setting(
        True,
        doc="track, generated: fit a smoothing spline to a noisy centre line "
        "(tracker.paths.centre_line; its noise estimated from the points) so the path's "
        "curvature is the road's, not the survey's; a clean line is taken as it is")
    default_width_m: float = setting(
        5.0, low=0.5, high=100.0, doc="track: half-width each side when the CSV has none")
    speed_profile: str = setting(
        "constant", choices=SPEED_PROFILES,
        doc="constant (speed_mps), friction-limited (curvature and friction: forward-"
        "backward pass with the accel limits below), stop-and-go (cruise, stop, go again)")
    lat_accel_max_mps2: float = setting(
        6.0, low=0.1, high=30.0,
        doc="friction-limited: lateral acceleration limit (at most grip_share of the "
        "believed friction, tracker.model.tyre_friction x g)")
    accel_max_mps2: float = setting(
        2.0, low=0.1, high=20.0,
        doc="friction-limited and stop-and-go: acceleration (friction-limited: at most "
        "tracking_share of tracker.accel_max_mps2 and what the believed power gives at "
        "the top speed)")
    decel_max_mps2: float = setting(
        3.0, low=0.1, high=20.0,
        doc="friction-limited and stop-and-go: braking (friction-limited: at most "
        "tracking_share of -tracker.accel_min_mps2 and grip_share of the believed friction)")
    grip_share: float = setting(
        0.7, low=0.05, high=1.0,
        doc="friction-limited: the share of the believed friction circle (mu g) the "
        "profile may use, laterally and in braking")
    tracking_share: float = setting(
        0.8, low=0.05, high=1.0,
        doc="friction-limited: the share of the tracker's acceleration bounds the profile "
        "may use; the rest is the speed loop's authority to catch up")
    cruise_s: float = setting(4.0, low=0.0, high=3600.0, doc="stop-and-go: time at speed")
    stop_s: float = setting(2.0, low=0.0, high=3600.0, doc="stop-and-go: time standing")


_PROFILE_KEYS: dict[str, tuple[str, ...]] = {
    "constant": (),
    "friction-limited": ("lat_accel_max_mps2", "accel_max_mps2", "decel_max_mps2",
                         "grip_share", "tracking_share"),
    "stop-and-go": ("accel_max_mps2", "decel_max_mps2", "cruise_s", "stop_s"),
}
_SHAPE_KEYS: dict[str, tuple[str, ...]] = {
    "double-lane-change": ("stretch", "length_m"),
    "straight": ("length_m",),
    "iso-lane-change": ("approach_m", "vehicle_width_m", "length_m"),
    "circle": ("radius_m",),
    "figure-eight": ("radius_m",),
    "slalom": ("spacing_m", "cones", "amplitude_m", "approach_m", "length_m"),
    "s-curve": ("radius_m", "arc_deg", "approach_m", "length_m"),
    "track": ("file", "closed", "smoothing", "default_width_m"),
    "generated": ("seed", "smoothing", "default_width_m"),
}


def path_keys_read(kind: str, speed_profile: str) -> tuple[str, ...]:
    """The ``path.*`` keys a path of ``kind`` with ``speed_profile`` reads
    (:func:`cosim.simulation.course.build_course`); the others are ignored."""
    return ("kind", "speed_mps", "speed_profile", *_SHAPE_KEYS[kind],
            *_PROFILE_KEYS[speed_profile])
