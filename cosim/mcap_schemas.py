"""JSON schemas of every MCAP channel cosim writes.

Plain, plottable fields for cosim's own topics; Foxglove's well-known schemas (by their
exact names ``foxglove.FrameTransform``, ``foxglove.SceneUpdate``, ``foxglove.LocationFix``;
field names from docs.foxglove.dev message-schemas) so Foxglove shows the run in 3D and on
a map without set-up. Foxglove encodes a time in JSON as ``{"sec": int, "nsec": int}``.
"""

from __future__ import annotations

from typing import Any

from cosim.sensors import TRUTH_FIELDS

NUMBER = {"type": "number"}
NUMBER_OR_NULL = {"type": ["number", "null"]}
NUMBERS = {"type": "array", "items": NUMBER}
NUMBERS_OR_NULL = {"type": "array", "items": NUMBER_OR_NULL}
STRING = {"type": "string"}
BOOLEAN = {"type": "boolean"}
INTEGER = {"type": "integer"}


def object_schema(title: str, properties: dict[str, Any], description: str = "") -> dict:
    return {
        "title": title,
        "description": description,
        "type": "object",
        "properties": properties,
    }


TIME = object_schema("time", {"sec": INTEGER, "nsec": INTEGER})
VECTOR3 = object_schema("foxglove.Vector3", {"x": NUMBER, "y": NUMBER, "z": NUMBER})
QUATERNION = object_schema(
    "foxglove.Quaternion", {"x": NUMBER, "y": NUMBER, "z": NUMBER, "w": NUMBER}
)
POSE = object_schema("foxglove.Pose", {"position": VECTOR3, "orientation": QUATERNION})
COLOR = object_schema("foxglove.Color", {"r": NUMBER, "g": NUMBER, "b": NUMBER, "a": NUMBER})

VEHICLE_STATE = object_schema(
    "cosim.VehicleState",
    {**{name: NUMBER for name in ("t_s", *TRUTH_FIELDS)}, "wheel_speed_radps": NUMBERS},
    "True state of the car: CoG position in the ENU world frame, velocities and "
    "accelerations in the ISO 8855 vehicle frame, wheels FL, FR, RL, RR.",
)

ESTIMATE = {
    **object_schema(
        "cosim.Estimate",
        {"t_s": NUMBER, "state_names": {"type": "array", "items": STRING},
         "covariance": NUMBERS},
        "Estimator mean (one field per estimated state, named as in /vehicle/truth) and "
        "its covariance, row-major over state_names.",
    ),
    "additionalProperties": NUMBER,
}

COMMAND = object_schema(
    "cosim.Command",
    {"t_s": NUMBER, "accel_mps2": NUMBER, "steer_rad": NUMBER,
     "drive_torque_nm": NUMBER, "brake_torque_nm": NUMBER},
    "Command as applied to the plant (after the actuator delay line) and the wheel torques "
    "the low-level layer made of it.",
)

PLAN = {
    **object_schema(
        "cosim.Plan",
        {"t_s": NUMBER, "dt_s": NUMBER, "cost": NUMBER_OR_NULL, "solve_time_s": NUMBER,
         "iterations": INTEGER, "status": STRING, "success": BOOLEAN, "fallback": BOOLEAN},
        "Tracker plan: predicted_<name> arrays over the horizon for each state and input.",
    ),
    "additionalProperties": NUMBERS_OR_NULL,
}

MEASUREMENT = {
    **object_schema(
        "cosim.Measurement",
        {"t_s": NUMBER, "sensor": STRING, "sigma": NUMBERS},
        "One sensor sample: one field per measured value, and each value's noise sigma.",
    ),
    "additionalProperties": NUMBER_OR_NULL,
}

DISTURBANCE = object_schema(
    "cosim.Disturbance",
    {"t_s": NUMBER, "kind": STRING, "heading_step_rad": NUMBER,
     "yaw_rate_change_radps": NUMBER},
    "An unmeasured disturbance applied to the plant (scenario `disturbances`).",
)

REFERENCE_PATH = object_schema(
    "cosim.ReferencePath",
    {"s_m": NUMBERS, "x_m": NUMBERS, "y_m": NUMBERS, "yaw_rad": NUMBERS,
     "curvature_1pm": NUMBERS, "speed_mps": NUMBER},
    "The reference path sampled along its arc length, world frame.",
)

METRICS = {
    **object_schema("cosim.Metrics", {"completed": BOOLEAN},
                    "Run metrics, the same object as `cosim inspect --json`'s metrics."),
    "additionalProperties": {"type": ["number", "boolean", "string", "null"]},
}

FRAME_TRANSFORM = object_schema(
    "foxglove.FrameTransform",
    {"timestamp": TIME, "parent_frame_id": STRING, "child_frame_id": STRING,
     "translation": VECTOR3, "rotation": QUATERNION},
)

_CUBE = object_schema("foxglove.CubePrimitive", {"pose": POSE, "size": VECTOR3, "color": COLOR})
_LINE = object_schema(
    "foxglove.LinePrimitive",
    {"type": INTEGER, "pose": POSE, "thickness": NUMBER, "scale_invariant": BOOLEAN,
     "points": {"type": "array", "items": VECTOR3}, "color": COLOR,
     "colors": {"type": "array", "items": COLOR}, "indices": {"type": "array", "items": INTEGER}},
)
_ENTITY = object_schema(
    "foxglove.SceneEntity",
    {"timestamp": TIME, "frame_id": STRING, "id": STRING, "lifetime": TIME,
     "frame_locked": BOOLEAN, "metadata": {"type": "array"},
     "arrows": {"type": "array"}, "cubes": {"type": "array", "items": _CUBE},
     "spheres": {"type": "array"}, "cylinders": {"type": "array"},
     "lines": {"type": "array", "items": _LINE}, "triangles": {"type": "array"},
     "texts": {"type": "array"}, "models": {"type": "array"}},
)
SCENE_UPDATE = object_schema(
    "foxglove.SceneUpdate",
    {"deletions": {"type": "array"}, "entities": {"type": "array", "items": _ENTITY}},
)

LOCATION_FIX = object_schema(
    "foxglove.LocationFix",
    {"timestamp": TIME, "frame_id": STRING, "latitude": NUMBER, "longitude": NUMBER,
     "altitude": NUMBER, "position_covariance": NUMBERS, "position_covariance_type": INTEGER},
)
