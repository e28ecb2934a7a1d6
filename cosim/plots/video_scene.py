"""What a video of a run shows, read from its log: the car's true track, the traffic, the
reference path, the frame times and the chase camera that follows the car.

Pure geometry on the logged values (no MuJoCo, no OpenGL): :mod:`cosim.plots.chase_renderer`
draws it, :mod:`cosim.plots.render` encodes it. The camera looks at a point just ahead of
the car from behind and above, at the car's heading smoothed by a first-order lag
(:data:`CHASE_HEADING_TIME_CONSTANT_S`) over the log's truth samples, so the view does not
depend on the frame rate.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim.core.exceptions import RenderError
from cosim.log import topics

CHASE_DISTANCE_M = 14.0
"""Distance from the camera to the point it looks at [m]."""

CHASE_ELEVATION_DEG = -17.0
"""Camera pitch: negative looks down onto the car [deg]."""

CHASE_LOOK_AHEAD_M = 3.0
"""The camera looks at a point this far ahead of the CoG along the smoothed heading, so
the car sits a little below the centre of the frame with road ahead of it [m]."""

CHASE_LOOK_HEIGHT_M = 1.0
"""Height above the ground of the point the camera looks at [m]."""

CHASE_HEADING_TIME_CONSTANT_S = 0.6
"""Time constant of the first-order lag between the car's yaw and the camera's heading [s]."""


@dataclass(frozen=True)
class TruthTrack:
    """The logged true pose of the car, one row per ``/vehicle/truth`` message.

    ``yaw_rad`` is unwrapped (continuous), so it can be interpolated and smoothed.
    """

    t_s: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    z_m: np.ndarray
    roll_rad: np.ndarray
    pitch_rad: np.ndarray
    yaw_rad: np.ndarray
    steer_rad: np.ndarray

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    def at(self, t_s: float) -> CarPose:
        """The pose at ``t_s`` (log time), interpolated linearly between samples and held
        at the ends."""
        def lerp(values: np.ndarray) -> float:
            return float(np.interp(t_s, self.t_s, values))

        return CarPose(lerp(self.x_m), lerp(self.y_m), lerp(self.z_m), lerp(self.roll_rad),
                       lerp(self.pitch_rad), lerp(self.yaw_rad), lerp(self.steer_rad))


@dataclass(frozen=True)
class CarPose:
    """Where the car is drawn: CoG position (world), orientation, road-wheel angle."""

    x_m: float
    y_m: float
    z_m: float
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    steer_rad: float


@dataclass(frozen=True)
class LoggedScene:
    """Everything a video needs from a log."""

    mjcf_xml: str
    assets: dict[str, bytes]
    model_source: str
    truth: TruthTrack
    path_xy_m: np.ndarray | None
    """Reference path points (N x 2, world frame), or None if the log has no path."""
    traffic: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    """Each traffic car's logged track: rows of (t_s, x_m, y_m, unwrapped yaw_rad)."""


def read_logged_scene(log_path: Path | str) -> LoggedScene:
    """Read the model, the truth and the reference path from a cosim MCAP log.

    Raises :class:`RenderError` if the log has no truth or no way to get the model.
    """
    from cosim.log.reader import iter_messages, read_attachment, read_summary

    log_path = Path(log_path)
    rows = [message for _, message in iter_messages(log_path, topics.VEHICLE_TRUTH)]
    if len(rows) < 2:
        raise RenderError(f"{str(log_path)!r}: {len(rows)} /vehicle/truth messages; expected "
                          "at least 2 to make a video")
    columns = {name: np.array([float(row.get(name, 0.0)) for row in rows])
               for name in ("t_s", "x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad",
                            "steer_rad")}
    columns["yaw_rad"] = np.unwrap(columns["yaw_rad"])
    truth = TruthTrack(**columns)
    if np.any(np.diff(truth.t_s) <= 0.0) or not all(
            np.all(np.isfinite(v)) for v in columns.values()):
        raise RenderError(f"{str(log_path)!r}: /vehicle/truth times are not increasing or "
                          "a value is not finite")

    path_xy = None
    for _, message in iter_messages(log_path, topics.REFERENCE_PATH):
        path_xy = np.column_stack([message["x_m"], message["y_m"]]).astype(float)
        break

    rows_by_car: dict[str, list[tuple[float, float, float, float]]] = {}
    for _, message in iter_messages(log_path, topics.TRAFFIC_CARS):
        for car in message["cars"]:
            rows_by_car.setdefault(car["name"], []).append(
                (car["t_s"], car["x_m"], car["y_m"], car["yaw_rad"]))
    traffic = {name: np.array(rows, dtype=float) for name, rows in rows_by_car.items()}
    for track in traffic.values():
        track[:, 3] = np.unwrap(track[:, 3])

    attached = read_attachment(log_path, "sedan.xml")
    if attached is not None:
        return LoggedScene(attached.decode(), {}, "attachment sedan.xml", truth, path_xy,
                           traffic)
    config = read_summary(log_path).config
    if not config.get("plant") or not config.get("sim"):
        raise RenderError(f"{str(log_path)!r}: neither the attachment sedan.xml nor a run "
                          "config to rebuild the model from")
    from cosim.core.config_fields import from_dict
    from cosim.core.key_aliases import rename_old_keys
    from cosim.core.vehicle_params import PlantConfig
    from cosim.plant.sedan_model import sedan_xml_and_assets

    logged = rename_old_keys({"plant": config["plant"]}, warn=False)  # an older log's keys
    plant = from_dict(PlantConfig, logged["plant"], "plant")
    xml, assets = sedan_xml_and_assets(plant, float(config["sim"]["physics_dt_s"]))
    return LoggedScene(xml, assets, "rebuilt from the config", truth, path_xy)


def frame_times(truth_t_s: np.ndarray, fps: float, start_s: float = 0.0,
                duration_s: float | None = None) -> np.ndarray:
    """Log times of the frames: ``t0 + start + k / fps`` up to the last truth sample (or
    ``start + duration``), ``t0`` the first truth sample. Raises :class:`RenderError` if
    ``start`` is past the end."""
    t0, t_last = float(truth_t_s[0]), float(truth_t_s[-1])
    end = t_last if duration_s is None else min(t_last, t0 + start_s + duration_s)
    span = end - (t0 + start_s)
    if span < -1e-9:
        raise RenderError(f"--start {start_s}: expected at most the log's length "
                          f"({t_last - t0:.3f} s)")
    count = math.floor(max(span, 0.0) * fps + 1e-6) + 1
    return t0 + start_s + np.arange(count) / fps


def smoothed_heading(t_s: np.ndarray, yaw_rad: np.ndarray,
                     time_constant_s: float = CHASE_HEADING_TIME_CONSTANT_S) -> np.ndarray:
    """First-order lag of the (unwrapped) yaw, sample by sample with the exact discretisation
    ``h_k = h_{k-1} + (1 - exp(-dt / tau)) (yaw_k - h_{k-1})``, starting at the first yaw."""
    heading = np.empty_like(yaw_rad)
    heading[0] = yaw_rad[0]
    gains = 1.0 - np.exp(-np.diff(t_s) / time_constant_s)
    for k, gain in enumerate(gains, start=1):
        heading[k] = heading[k - 1] + gain * (yaw_rad[k] - heading[k - 1])
    return heading


@dataclass(frozen=True)
class ChaseView:
    """A free MuJoCo camera (``mjvCamera``): the point looked at, distance and angles."""

    lookat_m: tuple[float, float, float]
    distance_m: float
    azimuth_deg: float
    elevation_deg: float


def chase_camera(x_m: float, y_m: float, heading_rad: float) -> ChaseView:
    """The chase camera behind a car at ``(x, y)`` heading ``heading_rad``.

    MuJoCo places a free camera at ``lookat - distance * (cos el cos az, cos el sin az,
    sin el)`` looking at ``lookat``; azimuth = heading puts it behind the car.
    """
    ahead_x = x_m + CHASE_LOOK_AHEAD_M * math.cos(heading_rad)
    ahead_y = y_m + CHASE_LOOK_AHEAD_M * math.sin(heading_rad)
    return ChaseView((ahead_x, ahead_y, CHASE_LOOK_HEIGHT_M), CHASE_DISTANCE_M,
                     math.degrees(heading_rad), CHASE_ELEVATION_DEG)


def path_segments(path_xy_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centres (N x 2), half lengths (N) and headings (N) of the segments joining the
    consecutive points of the path (zero-length segments dropped)."""
    start, end = path_xy_m[:-1], path_xy_m[1:]
    delta = end - start
    length = np.hypot(delta[:, 0], delta[:, 1])
    keep = length > 1e-9
    return (0.5 * (start + end))[keep], 0.5 * length[keep], np.arctan2(
        delta[keep, 1], delta[keep, 0])
