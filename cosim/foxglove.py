"""Foxglove visualisation messages: the car's transform, the 3D scene and a map fix.

Frames: ``world`` (ENU, the run's origin) and ``base_link`` (the car's CoG, ISO 8855).
The scene is sent once: the reference path as a line in ``world`` and the car body as a
frame-locked cube in ``base_link``, which then follows the ``/tf`` transforms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cosim.config_fields import setting
from cosim.records import VehicleState
from cosim.vehicle_params import VehicleParams

EARTH_RADIUS_M = 6_378_137.0
"""WGS-84 equatorial radius."""


@dataclass(frozen=True)
class GeoOrigin:
    """Geodetic position of the world frame's origin, for Foxglove's map panel."""

    latitude_deg: float = setting(48.1351, low=-89.0, high=89.0)
    longitude_deg: float = setting(11.5820, low=-180.0, high=180.0)
    altitude_m: float = setting(520.0, low=-500.0, high=9000.0)


def _time(t_s: float) -> dict[str, int]:
    t_ns = round(t_s * 1e9)
    return {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000}


def quaternion_from_euler(roll_rad: float, pitch_rad: float, yaw_rad: float) -> dict[str, float]:
    """Z-Y-X (yaw, pitch, roll) Euler angles to a unit quaternion."""
    cr, sr = math.cos(roll_rad / 2), math.sin(roll_rad / 2)
    cp, sp = math.cos(pitch_rad / 2), math.sin(pitch_rad / 2)
    cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
    return {
        "x": sr * cp * cy - cr * sp * sy,
        "y": cr * sp * cy + sr * cp * sy,
        "z": cr * cp * sy - sr * sp * cy,
        "w": cr * cp * cy + sr * sp * sy,
    }


def frame_transform(truth: VehicleState) -> dict[str, object]:
    """``foxglove.FrameTransform`` world -> base_link at the car's CoG."""
    return {
        "timestamp": _time(truth.t_s),
        "parent_frame_id": "world",
        "child_frame_id": "base_link",
        "translation": {"x": truth.x_m, "y": truth.y_m, "z": truth.z_m},
        "rotation": quaternion_from_euler(truth.roll_rad, truth.pitch_rad, truth.yaw_rad),
    }


def location_fix(x_m: float, y_m: float, t_s: float, sigma_m: float,
                 origin: GeoOrigin) -> dict[str, object]:
    """``foxglove.LocationFix`` of a world-frame position (local flat-earth approximation,
    accurate to centimetres over the kilometre a run covers)."""
    lat0 = math.radians(origin.latitude_deg)
    latitude = origin.latitude_deg + math.degrees(y_m / EARTH_RADIUS_M)
    longitude = origin.longitude_deg + math.degrees(x_m / (EARTH_RADIUS_M * math.cos(lat0)))
    variance = sigma_m**2
    return {
        "timestamp": _time(t_s),
        "frame_id": "world",
        "latitude": latitude,
        "longitude": longitude,
        "altitude": origin.altitude_m,
        "position_covariance": [variance, 0, 0, 0, variance, 0, 0, 0, variance],
        "position_covariance_type": 2,  # DIAGONAL_KNOWN
    }


_IDENTITY_POSE = {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
                  "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}


def static_scene(path_x_m: np.ndarray, path_y_m: np.ndarray,
                 params: VehicleParams) -> dict[str, object]:
    """``foxglove.SceneUpdate`` with the reference path and the car body (frame-locked)."""
    length = params.wheelbase_m + 1.9  # overhangs of a typical sedan
    body_centre_x = (params.cog_front_m + 1.0 - params.cog_rear_m - 0.9) / 2
    forever = {"sec": 0, "nsec": 0}
    path_entity = {
        "timestamp": _time(0.0), "frame_id": "world", "id": "reference_path",
        "lifetime": forever, "frame_locked": False, "metadata": [],
        "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "triangles": [],
        "texts": [], "models": [],
        "lines": [{
            "type": 0, "pose": _IDENTITY_POSE, "thickness": 0.1, "scale_invariant": False,
            "points": [{"x": float(x), "y": float(y), "z": 0.02}
                       for x, y in zip(path_x_m, path_y_m, strict=True)],
            "color": {"r": 0.1, "g": 0.8, "b": 0.2, "a": 1.0}, "colors": [], "indices": [],
        }],
    }
    car_entity = {
        "timestamp": _time(0.0), "frame_id": "base_link", "id": "car_body",
        "lifetime": forever, "frame_locked": True, "metadata": [],
        "arrows": [], "spheres": [], "cylinders": [], "lines": [], "triangles": [],
        "texts": [], "models": [],
        "cubes": [{
            "pose": {"position": {"x": body_centre_x, "y": 0.0, "z": 0.1},
                     "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
            "size": {"x": length, "y": params.track_m + 0.2, "z": 1.4},
            "color": {"r": 0.2, "g": 0.4, "b": 0.9, "a": 0.8},
        }],
    }
    return {"deletions": [], "entities": [path_entity, car_entity]}
