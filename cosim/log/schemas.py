"""JSON schemas of every MCAP channel cosim writes.

Plain, plottable fields for cosim's own topics; Foxglove's well-known schemas (by their
exact names ``foxglove.FrameTransform``, ``foxglove.SceneUpdate``, ``foxglove.LocationFix``;
field names and constraints from docs.foxglove.dev message-schemas and the JSON schemas of
github.com/foxglove/schemas) so Foxglove shows the run in 3D and on a map without set-up.
Foxglove encodes a time or a duration in JSON as ``{"sec": int, "nsec": int}``.
"""

from __future__ import annotations

from typing import Any

from cosim.sensing.sensors import TRUTH_FIELDS, ImuSensor

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


NSEC = {"type": "integer", "minimum": 0, "maximum": 999_999_999}
TIME = object_schema("time", {"sec": {"type": "integer", "minimum": 0}, "nsec": NSEC})
DURATION = object_schema("duration", {"sec": INTEGER, "nsec": NSEC})
VECTOR3 = object_schema("foxglove.Vector3", {"x": NUMBER, "y": NUMBER, "z": NUMBER})
QUATERNION = object_schema(
    "foxglove.Quaternion", {"x": NUMBER, "y": NUMBER, "z": NUMBER, "w": NUMBER}
)
POSE = object_schema("foxglove.Pose", {"position": VECTOR3, "orientation": QUATERNION})
COLOR = object_schema("foxglove.Color", {"r": NUMBER, "g": NUMBER, "b": NUMBER, "a": NUMBER})

VEHICLE_STATE = object_schema(
    "cosim.VehicleState",
    {**{name: NUMBER for name in ("t_s", *TRUTH_FIELDS)}, "wheel_speed_radps": NUMBERS,
     **{name: NUMBER for name in ImuSensor.BIAS_NAMES}},
    "True state of the car: CoG position in the ENU world frame, velocities and "
    "accelerations in the ISO 8855 vehicle frame, wheels FL, FR, RL, RR; with an IMU, the "
    "true bias of each of its channels (gyro_bias_radps, ax_bias_mps2, ay_bias_mps2).",
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
         "iterations": INTEGER, "status": STRING, "success": BOOLEAN, "fallback": BOOLEAN,
         "speed_reduced": BOOLEAN},
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

EVENT = object_schema(
    "cosim.Event",
    {"t_s": NUMBER, "kind": STRING, "value": NUMBER_OR_NULL, "threshold": NUMBER_OR_NULL,
     "detail": STRING},
    "Something that happened in the run (an outcome event: spun, rolled_over, off_road, "
    "end_of_path, collision): its simulated time, the value that crossed the threshold.",
)

TRACKING_ERRORS = object_schema(
    "cosim.TrackingErrors",
    {"t_s": NUMBER, "cte_m": NUMBER, "heading_err_rad": NUMBER, "speed_err_mps": NUMBER,
     "speed_mps": NUMBER, "ref_speed_mps": NUMBER},
    "Tracking errors of the true CoG at each log step, as the metrics compute them: "
    "cross-track error (positive left of the path), heading error (true yaw minus the "
    "path's yaw at the projection), speed minus the reference speed.",
)

REFERENCE_PATH = object_schema(
    "cosim.ReferencePath",
    {"s_m": NUMBERS, "x_m": NUMBERS, "y_m": NUMBERS, "yaw_rad": NUMBERS,
     "curvature_1pm": NUMBERS, "speed_mps": NUMBER, "ref_speed_mps": NUMBERS,
     "closed": BOOLEAN},
    "The reference path sampled along its arc length, world frame; speed_mps is the top "
    "speed, ref_speed_mps the speed profile at t = 0; closed for a circuit.",
)

METRICS = {
    **object_schema("cosim.Metrics", {"completed": BOOLEAN},
                    "Run metrics, the same object as `cosim inspect --json`'s metrics."),
    "additionalProperties": {"type": ["number", "boolean", "string", "null"]},
}

LIVE_METRICS = {
    **object_schema("cosim.LiveMetrics", {"t_s": NUMBER},
                    "Running metrics over the run so far, once per second of sim time: the "
                    "keys of /metrics that can be computed before the end, plus cte_m now."),
    "additionalProperties": {"type": ["number", "null"]},
}

ESTIMATOR_UPDATE = object_schema(
    "cosim.EstimatorUpdate",
    {"t_s": NUMBER, "sensor": STRING, "accepted": BOOLEAN, "nis": NUMBER_OR_NULL,
     "dof": {"type": "integer"}, "reason": STRING},
    "One measurement fused (or refused) by the estimator: its normalised innovation squared "
    "against the prior and its degrees of freedom (NIS / dof is about 1 for a consistent "
    "filter; Bar-Shalom, Li, Kirubarajan 2001, sec. 5.4).",
)

FRAME_TRANSFORM = object_schema(
    "foxglove.FrameTransform",
    {"timestamp": TIME, "parent_frame_id": STRING, "child_frame_id": STRING,
     "translation": VECTOR3, "rotation": QUATERNION},
)

_ARROW = object_schema(
    "foxglove.ArrowPrimitive",
    {"pose": POSE, "shaft_length": NUMBER, "shaft_diameter": NUMBER, "head_length": NUMBER,
     "head_diameter": NUMBER, "color": COLOR},
)
_CUBE = object_schema("foxglove.CubePrimitive", {"pose": POSE, "size": VECTOR3, "color": COLOR})
_SPHERE = object_schema(
    "foxglove.SpherePrimitive", {"pose": POSE, "size": VECTOR3, "color": COLOR}
)
_CYLINDER = object_schema(
    "foxglove.CylinderPrimitive",
    {"pose": POSE, "size": VECTOR3, "bottom_scale": NUMBER, "top_scale": NUMBER,
     "color": COLOR},
)
_LINE = object_schema(
    "foxglove.LinePrimitive",
    {"type": {"type": "integer", "enum": [0, 1, 2]},  # LINE_STRIP, LINE_LOOP, LINE_LIST
     "pose": POSE, "thickness": NUMBER, "scale_invariant": BOOLEAN,
     "points": {"type": "array", "items": VECTOR3}, "color": COLOR,
     "colors": {"type": "array", "items": COLOR}, "indices": {"type": "array", "items": INTEGER}},
)
_ENTITY = object_schema(
    "foxglove.SceneEntity",
    {"timestamp": TIME, "frame_id": STRING, "id": STRING, "lifetime": DURATION,
     "frame_locked": BOOLEAN, "metadata": {"type": "array"},
     "arrows": {"type": "array", "items": _ARROW},
     "cubes": {"type": "array", "items": _CUBE},
     "spheres": {"type": "array", "items": _SPHERE},
     "cylinders": {"type": "array", "items": _CYLINDER},
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
     "altitude": NUMBER,
     "position_covariance": {**NUMBERS, "minItems": 9, "maxItems": 9},
     "position_covariance_type": {"type": "integer", "enum": [0, 1, 2, 3]}},
)

TRAFFIC_CARS = object_schema(
    "cosim.TrafficCars",
    {"t_s": NUMBER, "cars": {"type": "array", "items": object_schema(
        "cosim.CarPose",
        {"name": STRING, "t_s": NUMBER, "x_m": NUMBER, "y_m": NUMBER, "yaw_rad": NUMBER,
         "speed_mps": NUMBER, "accel_mps2": NUMBER, "length_m": NUMBER, "width_m": NUMBER})}},
    "Every traffic car's true pose (centre of its footprint, ENU world frame) and motion.",
)

RANGE_READING = object_schema(
    "cosim.RangeReading",
    {"t_s": NUMBER, "target": STRING, "gap_m": NUMBER_OR_NULL,
     "range_rate_mps": NUMBER_OR_NULL},
    "One sample of the ego's forward range sensor: the target car's name (empty: none), "
    "the gap from the front bumper to its rear and the range rate, with noise.",
)

TRAFFIC_GAP = object_schema(
    "cosim.TrafficGap",
    {"t_s": NUMBER, "target": STRING, "gap_m": NUMBER_OR_NULL,
     "range_rate_mps": NUMBER_OR_NULL, "time_gap_s": NUMBER_OR_NULL, "ttc_s": NUMBER_OR_NULL,
     "safe_gap_m": NUMBER_OR_NULL, "target_speed_mps": NUMBER_OR_NULL},
    "The true gap to the nearest car ahead in the ego's lane, its time gap and time to "
    "collision (null when not closing), and the minimum safe gap at the ego's speed.",
)

ACC_GAINS = object_schema(
    "cosim.AccGains",
    {"t_s": NUMBER, **{name: NUMBER for name in ("k_v", "k_x", "k_vrel", "k_v_estimate",
                                                  "k_x_estimate", "k_vrel_estimate")}},
    "The ACC's gains as applied (extremum seeking's estimate plus its perturbation) and "
    "the estimates themselves.",
)

ACC_OBJECTIVE = object_schema(
    "cosim.AccObjective",
    {"t_s": NUMBER, "objective": NUMBER_OR_NULL},
    "The objective extremum seeking minimises, at each control step.",
)

ACC_MODE = object_schema(
    "cosim.AccMode",
    {"t_s": NUMBER, "mode": STRING, "gap_mode": BOOLEAN, "target": STRING,
     "gap_m": NUMBER_OR_NULL, "desired_gap_m": NUMBER, "range_rate_mps": NUMBER_OR_NULL,
     "speed_mps": NUMBER, "accel_mps2": NUMBER},
    "The ACC's mode (speed or gap) and what it decided from: the target and gap it used, "
    "the desired gap, the estimated speed, the commanded acceleration.",
)
