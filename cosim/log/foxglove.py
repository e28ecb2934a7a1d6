"""Foxglove visualisation messages: the car's transform, the 3D scene and a map fix.

Frames: ``world`` (ENU, the run's origin, the ground at z = 0) and ``base_link`` (the car's
CoG, ISO 8855: x forward, y left, z up; it rolls and pitches with the body).

The scene is split over topics by how often it changes, and every message of a topic is
complete on its own: when Foxglove seeks, it shows the last message of each topic, so a
topic whose messages only add to earlier ones would lose them.

- ``/scene``: once, the reference path (a line in ``world``);
- ``/scene/car``: every log step, the car body and its four wheels (frame-locked in
  ``base_link``, so ``/tf`` moves them; the front wheels turn by the true road-wheel angle);
- ``/scene/plan``: every control step, the tracker's predicted path (a line in ``world``);
- ``/scene/estimate``: every log step, the estimated pose (an arrow) and its n-sigma
  position ellipse (a flat ellipsoid) in ``world``.

Each entity keeps its ``id`` from message to message, so each message replaces the last.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cosim.core.config_fields import setting
from cosim.core.records import Estimate, Plan, VehicleState
from cosim.core.rotations import quaternion_zyx
from cosim.core.vehicle_params import CarParams

WGS84_A_M = 6_378_137.0
"""WGS-84 semi-major axis (equatorial radius)."""
WGS84_E2 = 6.694_379_990_14e-3
"""WGS-84 first eccentricity squared."""

WORLD_FRAME = "world"
CAR_FRAME = "base_link"

FRONT_OVERHANG_M = 1.0
"""Front axle to front bumper of a typical sedan."""
REAR_OVERHANG_M = 0.9
"""Rear axle to rear bumper."""
BODY_WIDTH_OVER_TRACK_M = 0.2
"""Body width minus the track."""
GROUND_CLEARANCE_M = 0.2
BELT_LINE_M = 0.95
"""Top of the lower body (bonnet, doors) above the ground."""
ROOF_M = 1.45
"""Roof above the ground."""
CABIN_LENGTH_FRACTION = 0.55
"""Cabin length / body length; the cabin sits 0.3 m behind the body's centre."""
TYRE_WIDTH_M = 0.22

PATH_Z_M = 0.02
"""Height of the reference path above the ground (drawn just above it)."""
CONE_HEIGHT_M = 0.7
"""Height of a traffic cone in the scene."""
CONE_BASE_M = 0.35
"""Base diameter of a traffic cone."""
PLAN_Z_M = 0.05
ESTIMATE_Z_M = 0.08

_IDENTITY = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
_FOREVER = {"sec": 0, "nsec": 0}


@dataclass(frozen=True)
class GeoOrigin:
    """Geodetic position of the world frame's origin, for Foxglove's map panel."""

    latitude_deg: float = setting(48.1351, low=-89.0, high=89.0)
    longitude_deg: float = setting(11.5820, low=-180.0, high=180.0)
    altitude_m: float = setting(520.0, low=-500.0, high=9000.0)


@dataclass(frozen=True)
class Ellipse:
    """A covariance ellipse in the x-y plane."""

    semi_major_m: float
    semi_minor_m: float
    angle_rad: float
    """Direction of the major axis, counter-clockwise from +x."""


def _time(t_s: float) -> dict[str, int]:
    t_ns = round(t_s * 1e9)
    return {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000}


def _color(r: float, g: float, b: float, a: float = 1.0) -> dict[str, float]:
    return {"r": r, "g": g, "b": b, "a": a}


def _vector(x: float, y: float, z: float) -> dict[str, float]:
    return {"x": float(x), "y": float(y), "z": float(z)}


def _pose(x: float, y: float, z: float,
          orientation: dict[str, float] | None = None) -> dict[str, Any]:
    return {"position": _vector(x, y, z), "orientation": orientation or _IDENTITY}


def _entity(t_s: float, frame_id: str, entity_id: str, frame_locked: bool,
            **primitives: list[dict[str, Any]]) -> dict[str, Any]:
    """``foxglove.SceneEntity`` that stays until an entity with its ``id`` replaces it."""
    entity: dict[str, Any] = {
        "timestamp": _time(t_s), "frame_id": frame_id, "id": entity_id,
        "lifetime": _FOREVER, "frame_locked": frame_locked, "metadata": [],
    }
    for kind in ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts",
                 "models"):
        entity[kind] = primitives.pop(kind, [])
    if primitives:
        raise ValueError(f"unknown primitive kinds {sorted(primitives)}")
    return entity


def _scene(*entities: dict[str, Any]) -> dict[str, Any]:
    return {"deletions": [], "entities": list(entities)}


def quaternion_from_euler(roll_rad: float, pitch_rad: float, yaw_rad: float) -> dict[str, float]:
    """Z-Y-X (yaw, pitch, roll) Euler angles to a ``foxglove.Quaternion``
    (:func:`cosim.core.rotations.quaternion_zyx`, as the plant sets the chassis)."""
    w, x, y, z = quaternion_zyx(yaw_rad, pitch_rad, roll_rad)
    return {"x": x, "y": y, "z": z, "w": w}


def frame_transform(truth: VehicleState) -> dict[str, object]:
    """``foxglove.FrameTransform`` world -> base_link: the CoG's position, the body's roll,
    pitch and yaw."""
    return {
        "timestamp": _time(truth.t_s),
        "parent_frame_id": WORLD_FRAME,
        "child_frame_id": CAR_FRAME,
        "translation": _vector(truth.x_m, truth.y_m, truth.z_m),
        "rotation": quaternion_from_euler(truth.roll_rad, truth.pitch_rad, truth.yaw_rad),
    }


def location_fix(x_m: float, y_m: float, t_s: float, sigma_m: float,
                 origin: GeoOrigin) -> dict[str, object]:
    """``foxglove.LocationFix`` of a world-frame position (east ``x_m``, north ``y_m``).

    Local tangent plane at ``origin`` with WGS-84's meridian and prime-vertical radii of
    curvature there; the error grows as distance^2 / R: under 2 cm within 300 m of the
    origin, about 0.2 m at 1 km.
    """
    lat0 = math.radians(origin.latitude_deg)
    w = math.sqrt(1.0 - WGS84_E2 * math.sin(lat0) ** 2)
    meridian_radius_m = WGS84_A_M * (1.0 - WGS84_E2) / w**3
    prime_vertical_radius_m = WGS84_A_M / w
    variance = sigma_m**2
    return {
        "timestamp": _time(t_s),
        "frame_id": CAR_FRAME,  # the antenna sits at the CoG
        "latitude": origin.latitude_deg + math.degrees(y_m / meridian_radius_m),
        "longitude": origin.longitude_deg
        + math.degrees(x_m / (prime_vertical_radius_m * math.cos(lat0))),
        "altitude": origin.altitude_m,
        "position_covariance": [variance, 0, 0, 0, variance, 0, 0, 0, variance],
        "position_covariance_type": 2,  # DIAGONAL_KNOWN
    }


def static_scene(path_x_m: np.ndarray, path_y_m: np.ndarray,
                 cones_xy_m: np.ndarray | None = None,
                 edges: tuple[np.ndarray, ...] | None = None,
                 closed: bool = False) -> dict[str, object]:
    """``foxglove.SceneUpdate`` with the reference path, and where the course has them, its
    cones (orange cones 0.7 m tall) and track edges ``(x_left, y_left, x_right, y_right)``
    as white lines (sent once, on ``/scene``)."""
    def line(x: np.ndarray, y: np.ndarray, color: dict[str, float],
             thickness: float) -> dict[str, Any]:
        points = [_vector(a, b, PATH_Z_M) for a, b in zip(x, y, strict=True)]
        if closed and points:
            points.append(points[0])
        return {"type": 0, "pose": _pose(0.0, 0.0, 0.0), "thickness": thickness,
                "scale_invariant": False, "points": points, "color": color, "colors": [],
                "indices": []}

    entities = [_entity(0.0, WORLD_FRAME, "reference_path", False,
                        lines=[line(path_x_m, path_y_m, _color(0.1, 0.8, 0.2), 0.1)])]
    if cones_xy_m is not None and len(cones_xy_m):
        cones = [{"pose": _pose(x, y, CONE_HEIGHT_M / 2),
                  "size": _vector(CONE_BASE_M, CONE_BASE_M, CONE_HEIGHT_M),
                  "bottom_scale": 1.0, "top_scale": 0.0, "color": _color(1.0, 0.45, 0.0)}
                 for x, y in cones_xy_m]
        entities.append(_entity(0.0, WORLD_FRAME, "cones", False, cylinders=cones))
    if edges is not None:
        white = _color(0.95, 0.95, 0.95)
        entities.append(_entity(0.0, WORLD_FRAME, "track_bounds", False,
                                lines=[line(edges[0], edges[1], white, 0.15),
                                       line(edges[2], edges[3], white, 0.15)]))
    return _scene(*entities)


def car_scene(truth: VehicleState, params: CarParams) -> dict[str, object]:
    """``foxglove.SceneUpdate``: the car body (lower body and cabin) and its four wheels in
    ``base_link``, frame-locked; both front wheels turn by the true road-wheel angle (the
    mean of the two: the Ackermann split is not shown)."""
    ground_z = -params.cog_height_m
    length = params.wheelbase_m + FRONT_OVERHANG_M + REAR_OVERHANG_M
    centre_x = (params.cog_front_m + FRONT_OVERHANG_M - params.cog_rear_m - REAR_OVERHANG_M) / 2
    width = params.widest_track_m + BODY_WIDTH_OVER_TRACK_M
    body = {
        "pose": _pose(centre_x, 0.0, ground_z + (GROUND_CLEARANCE_M + BELT_LINE_M) / 2),
        "size": _vector(length, width, BELT_LINE_M - GROUND_CLEARANCE_M),
        "color": _color(0.2, 0.4, 0.9, 0.6),
    }
    cabin = {
        "pose": _pose(centre_x - 0.3, 0.0, ground_z + (BELT_LINE_M + ROOF_M) / 2),
        "size": _vector(CABIN_LENGTH_FRACTION * length, width - 0.2, ROOF_M - BELT_LINE_M),
        "color": _color(0.6, 0.75, 0.95, 0.5),
    }
    diameter = 2 * params.wheel_radius_m
    wheels = []
    track_front, track_rear = params.axle_tracks_m
    for x_m, steer_rad, track_m in ((params.cog_front_m, truth.steer_rad, track_front),
                                    (-params.cog_rear_m, 0.0, track_rear)):
        # A cylinder's axis is its z: roll it by 90 deg onto the axle, then steer it.
        orientation = quaternion_from_euler(math.pi / 2, 0.0, steer_rad)
        for y_m in (track_m / 2, -track_m / 2):
            wheels.append({
                "pose": _pose(x_m, y_m, ground_z + params.wheel_radius_m, orientation),
                "size": _vector(diameter, diameter, TYRE_WIDTH_M),
                "bottom_scale": 1.0, "top_scale": 1.0,
                "color": _color(0.1, 0.1, 0.1, 1.0),
            })
    return _scene(_entity(truth.t_s, CAR_FRAME, "car", True, cubes=[body, cabin],
                          cylinders=wheels))


def plan_scene(plan: Plan) -> dict[str, object] | None:
    """``foxglove.SceneUpdate``: the tracker's predicted CoG path as a line in ``world``.

    None for a plan without world positions (``dynamic-mpc`` predicts path-error
    coordinates); nodes with a non-finite position are left out (an entity without points
    hides the last line).
    """
    if "x_m" not in plan.state_names or "y_m" not in plan.state_names:
        return None
    x_m, y_m = plan.column("x_m"), plan.column("y_m")
    finite = np.isfinite(x_m) & np.isfinite(y_m)
    z_m = float(PLAN_Z_M)
    points = [{"x": round(x, 4), "y": round(y, 4), "z": z_m}  # a foxglove.Vector3 each
              for x, y in zip(x_m[finite].tolist(), y_m[finite].tolist(), strict=True)]
    lines = [{
        "type": 0, "pose": _pose(0.0, 0.0, 0.0), "thickness": 0.08, "scale_invariant": False,
        "points": points, "color": _color(1.0, 0.55, 0.0), "colors": [], "indices": [],
    }] if len(points) >= 2 else []
    return _scene(_entity(plan.t_s, WORLD_FRAME, "plan", False, lines=lines))


def covariance_ellipse(covariance_xy: np.ndarray, n_sigma: float) -> Ellipse:
    """The ``n_sigma`` ellipse of a 2x2 position covariance ``[[a, b], [b, c]]``: semi-axes
    ``n_sigma`` times the square roots of its eigenvalues, the major one along the
    eigenvector of the larger. In closed form (a 2x2 symmetric matrix's eigenvalues are
    ``(a + c) / 2 +- r`` with ``r = hypot((a - c) / 2, b)``, its larger eigenvector at
    ``atan2(2 b, a - c) / 2`` from +x), a tenth of LAPACK's call for the scene written 25
    times a second; a negative eigenvalue of a covariance rounded below zero counts as 0.
    The angle is in (-pi/2, pi/2]: an ellipse is the same turned by pi."""
    a, b, c = float(covariance_xy[0, 0]), float(covariance_xy[0, 1]), float(covariance_xy[1, 1])
    mean, radius = 0.5 * (a + c), math.hypot(0.5 * (a - c), b)
    major, minor = math.sqrt(max(mean + radius, 0.0)), math.sqrt(max(mean - radius, 0.0))
    return Ellipse(n_sigma * major, n_sigma * minor, 0.5 * math.atan2(2.0 * b, a - c))


_POSITION = ("x_m", "y_m")


def estimate_scene(estimate: Estimate, n_sigma: float = 3.0) -> dict[str, object]:
    """``foxglove.SceneUpdate``: the estimated pose (an arrow along the estimated yaw) and
    the ``n_sigma`` ellipse of the x-y covariance (a flat ellipsoid whose x and y sizes are
    the ellipse's axes) in ``world``. A non-finite position shows nothing; the ellipse is
    left out when the covariance is not finite."""
    x_m, y_m = estimate["x_m"], estimate["y_m"]
    if not (math.isfinite(x_m) and math.isfinite(y_m)):
        return _scene(_entity(estimate.t_s, WORLD_FRAME, "estimate", False))
    magenta = (0.85, 0.1, 0.75)
    arrows: list[dict[str, Any]] = []
    spheres: list[dict[str, Any]] = []
    if "yaw_rad" in estimate and math.isfinite(estimate["yaw_rad"]):
        arrows.append({
            "pose": _pose(x_m, y_m, ESTIMATE_Z_M,
                          quaternion_from_euler(0.0, 0.0, estimate["yaw_rad"])),
            "shaft_length": 1.2, "shaft_diameter": 0.06, "head_length": 0.4,
            "head_diameter": 0.18, "color": _color(*magenta),
        })
    covariance = estimate.sub_covariance(_POSITION)
    if np.isfinite(covariance).all():
        ellipse = covariance_ellipse(covariance, n_sigma)
        spheres.append({
            "pose": _pose(x_m, y_m, ESTIMATE_Z_M,
                          quaternion_from_euler(0.0, 0.0, ellipse.angle_rad)),
            "size": _vector(2 * ellipse.semi_major_m, 2 * ellipse.semi_minor_m, 0.01),
            "color": _color(*magenta, 0.35),
        })
    return _scene(_entity(estimate.t_s, WORLD_FRAME, "estimate", False, arrows=arrows,
                          spheres=spheres))


TRAFFIC_CAR_HEIGHT_M = 1.45
"""Height of a traffic car's box in the scene (``models/traffic_car.xml``)."""


def traffic_scene(t_s: float, cars: list[dict[str, Any]], target: str) -> dict[str, object]:
    """``foxglove.SceneUpdate``: each traffic car (a ``cosim.CarPose`` message) as a box in
    ``world``, the range sensor's current target in orange, the others in grey."""
    entities = []
    for car in cars:
        color = _color(1.0, 0.5, 0.0, 0.8) if car["name"] == target else _color(0.5, 0.5, 0.55, 0.8)
        box = {"pose": _pose(car["x_m"], car["y_m"], TRAFFIC_CAR_HEIGHT_M / 2,
                             quaternion_from_euler(0.0, 0.0, car["yaw_rad"])),
               "size": _vector(car["length_m"], car["width_m"], TRAFFIC_CAR_HEIGHT_M),
               "color": color}
        entities.append(_entity(t_s, WORLD_FRAME, f"traffic/{car['name']}", False,
                                cubes=[box]))
    return _scene(*entities)
