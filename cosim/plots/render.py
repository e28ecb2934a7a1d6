"""A video of a logged run: MuJoCo's offscreen renderer behind the car, encoded to MP4.

    cosim render FILE.mcap [--out VIDEO.mp4] [--fps N] [--width W] [--height H]
                           [--start S] [--duration S] [--gl osmesa|egl|glfw]

How a frame is made:

1. **The scene comes from the log.** The MJCF attachment ``sedan.xml`` is the model that
   was simulated (its textures are MuJoCo built-ins, so it needs no asset files); a log
   without it gets the model rebuilt from its ``run`` config with
   :func:`cosim.plant.sedan_model.sedan_xml_and_assets`, the plant's own builder.
2. **The car is posed from the truth.** ``/vehicle/truth`` (100 Hz) is interpolated
   linearly at each frame's time: the free joint gets the CoG position and the orientation
   from yaw, pitch and roll (intrinsic z-y'-x'', ISO 8855); the front wheels get their
   Ackermann angles of the logged ``steer_rad``. Nothing is simulated: ``mj_forward``
   only places the bodies.
3. **A chase camera follows it** (:func:`chase_camera`): it looks at a point just ahead of
   the car from behind and above, at the car's heading smoothed by a first-order lag
   (:data:`CHASE_HEADING_TIME_CONSTANT_S`), so a lane change swings the car in the frame
   instead of jerking the whole picture. The smoothing runs over the log's truth samples,
   so the view does not depend on the frame rate.
4. **The reference path** (``/reference/path``) is painted on the ground as thin flat
   boxes added to the renderer's scene after ``update_scene`` (``mjv_initGeom``): drawn,
   not simulated, and never part of the model.
5. **Frames go to ffmpeg** through a pipe (``imageio_ffmpeg.write_frames``, the ffmpeg
   binary that the ``imageio-ffmpeg`` wheel ships): H.264 (libx264), yuv420p, which every
   player opens. The video is written to a ``.partial`` file and renamed when complete.

Frame ``k`` shows the car at ``start + k / fps`` (seconds since the log's first truth
sample), for every such time up to the end of the log or of ``--duration``.

**The OpenGL back-end.** MuJoCo picks how it gets an OpenGL context from the ``MUJOCO_GL``
environment variable, once, when ``mujoco`` is first imported; the plant imports it with
``MUJOCO_GL=disable`` (the Makefile's setting; no context needed to simulate). So
:func:`render_log` runs the renderer in a child process (``python -m cosim.plots.render``,
private protocol: one JSON request in argv, JSON lines of progress and result on stdout)
whose environment sets ``MUJOCO_GL`` and ``PyOpenGL``'s ``PYOPENGL_PLATFORM`` to the chosen
back-end; the caller may have imported ``mujoco`` any way it liked. Back-ends
(:data:`GL_BACKENDS`): ``osmesa`` renders in software on any CPU (the default unless
``MUJOCO_GL`` names another one; Debian/Ubuntu package ``libosmesa6``), ``egl`` renders
headless on a GPU (``libegl1`` and the GPU's driver), ``glfw`` needs a display. A missing
back-end is a :class:`~cosim.core.exceptions.GlBackendError` naming the package to install.

Software rendering (OSMesa's llvmpipe) costs about 12 ms per 640x360 frame and 27 ms per
1280x720 one; MuJoCo's shadow map would cost five times that, so shadows and multisampling
are off (the sun still shades the faces).

Traffic cars (``car_<name>/`` mocap bodies of the attached MJCF) are posed from
``/traffic/cars``, interpolated like the ego. Not drawn yet: wheel spin (the rims are plain
cylinders).
"""

from __future__ import annotations

import ctypes.util
import dataclasses
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cosim.core.exceptions import CosimError, GlBackendError, RenderError
from cosim.core.rotations import quaternion_zyx
from cosim.log import topics

if TYPE_CHECKING:
    import mujoco

GL_BACKENDS: tuple[str, ...] = ("osmesa", "egl", "glfw")
"""The values of ``--gl`` (and of ``MUJOCO_GL`` that rendering honours)."""

DEFAULT_GL = "osmesa"
"""Back-end when ``MUJOCO_GL`` is unset or ``disable``: software, works without a GPU."""

GL_MISSING: dict[str, str] = {
    "osmesa": "the OSMesa library (libOSMesa) is not installed",
    "egl": "the EGL library (libEGL) is not installed",
    "glfw": "GLFW needs a display (DISPLAY and WAYLAND_DISPLAY are unset)",
}
"""What :func:`check_gl_backend` found missing, per back-end."""

GL_REMEDIES: dict[str, str] = {
    "osmesa": "install OSMesa (Debian/Ubuntu: apt-get install libosmesa6; Fedora: dnf install "
              "mesa-libOSMesa) or render on a GPU with --gl egl",
    "egl": "install EGL with the GPU's driver (Debian/Ubuntu: apt-get install libegl1) or "
           "render in software with --gl osmesa",
    "glfw": "render headless with --gl osmesa (software) or --gl egl (GPU)",
}
"""What the user can do about a back-end that is missing or does not start."""


VIDEO_SUFFIXES: tuple[str, ...] = (".mp4", ".mov", ".mkv")
"""Containers that hold H.264 video; ``--out`` must end with one of them."""

MAX_FRAME_SIZE_PX = 4096
"""Largest ``--width``/``--height`` [px] (MuJoCo's offscreen buffer is made this big)."""

VIDEO_CRF = 23
"""libx264 constant rate factor (0 lossless .. 51 worst; 23 is x264's default)."""

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

PATH_RGBA: tuple[float, float, float, float] = (1.0, 0.78, 0.1, 1.0)
"""Colour of the painted reference path (amber)."""

PATH_HALF_WIDTH_M = 0.12
"""Half the width of the painted reference path [m]."""

PATH_HEIGHT_M = 0.005
"""Height of the paint above the ground (clear of the ground's depth) [m]."""

PATH_DRAW_RADIUS_M = 150.0
"""Only path segments within this distance of the car are drawn (the haze hides the rest)
[m]."""

SKY_RGB: tuple[float, float, float] = (0.45, 0.62, 0.85)
"""Colour of the sky overhead (a gradient to :data:`SKY_HORIZON_RGB`)."""

SKY_HORIZON_RGB: tuple[float, float, float] = (0.92, 0.94, 0.96)
"""Colour of the sky at the horizon."""

VISIBILITY_M = 250.0
"""Far clipping distance of the camera [m]."""


@dataclass(frozen=True)
class RenderOptions:
    """What ``cosim render`` makes: frame rate, size, time window and GL back-end."""

    fps: float = 30.0
    """Frames per second of the video [1/s]."""
    width: int = 640
    """Frame width [px], even (yuv420p halves the chroma resolution)."""
    height: int = 360
    """Frame height [px], even."""
    start_s: float = 0.0
    """Time of the first frame, since the log's first truth sample [s]."""
    duration_s: float | None = None
    """Length of the video [s]; None: to the end of the log."""
    gl: str | None = None
    """OpenGL back-end (one of :data:`GL_BACKENDS`); None: :func:`default_gl`."""

    def validate(self) -> None:
        """Raise :class:`RenderError` naming the first bad option."""
        if not (math.isfinite(self.fps) and 0.0 < self.fps <= 240.0):
            raise RenderError(f"--fps {self.fps}: expected frames per second in (0, 240]")
        for name, value in (("--width", self.width), ("--height", self.height)):
            if not (16 <= value <= MAX_FRAME_SIZE_PX and value % 2 == 0):
                raise RenderError(f"{name} {value}: expected an even number of pixels in "
                                  f"[16, {MAX_FRAME_SIZE_PX}]")
        if not (math.isfinite(self.start_s) and self.start_s >= 0.0):
            raise RenderError(f"--start {self.start_s}: expected a number of seconds >= 0")
        if self.duration_s is not None and not (
                math.isfinite(self.duration_s) and self.duration_s >= 0.0):
            raise RenderError(f"--duration {self.duration_s}: expected a number of seconds "
                              ">= 0")
        if self.gl is not None and self.gl not in GL_BACKENDS:
            raise RenderError(f"--gl {self.gl!r}: expected one of {', '.join(GL_BACKENDS)}")


@dataclass(frozen=True)
class RenderResult:
    """What :func:`render_log` made."""

    path: Path
    frames: int
    fps: float
    width: int
    height: int
    gl: str
    """The OpenGL back-end that rendered."""
    model_source: str
    """Where the MJCF came from: ``attachment sedan.xml`` or ``rebuilt from the config``."""
    render_s_per_frame: float
    """Wall time per frame: posing, rendering and reading the pixels back (not encoding)."""
    wall_time_s: float
    """Wall time of the whole child process's work: reading, rendering, encoding."""

    @property
    def size_bytes(self) -> int:
        return self.path.stat().st_size

    def to_dict(self) -> dict[str, Any]:
        values = dataclasses.asdict(self)
        values["path"] = str(self.path)
        return values


# --------------------------------------------------------------------- the logged run


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
    from cosim.core.vehicle_params import PlantConfig
    from cosim.plant.sedan_model import sedan_xml_and_assets

    plant = from_dict(PlantConfig, config["plant"], "plant")
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


# ------------------------------------------------------------------- the GL back-end


def default_gl(environ: dict[str, str] | os._Environ[str] = os.environ) -> str:
    """``MUJOCO_GL`` if it names a back-end of :data:`GL_BACKENDS`, else :data:`DEFAULT_GL`
    (``disable``, the simulation's setting, and unset both mean "choose for me")."""
    value = environ.get("MUJOCO_GL", "").strip().lower()
    return value if value in GL_BACKENDS else DEFAULT_GL


def check_gl_backend(gl: str, environ: dict[str, str] | os._Environ[str] = os.environ,
                     find_library: Callable[[str], str | None] = ctypes.util.find_library
                     ) -> None:
    """Raise :class:`GlBackendError` with an install hint if ``gl`` cannot work here.

    A cheap check before MuJoCo tries (and fails less legibly): the shared library of
    ``osmesa``/``egl`` must be found by the dynamic loader, ``glfw`` needs a display.
    """
    if gl not in GL_BACKENDS:
        raise GlBackendError(f"MUJOCO_GL={gl}: expected one of {', '.join(GL_BACKENDS)}")
    if gl == "osmesa":
        missing = find_library("OSMesa") is None
    elif gl == "egl":
        missing = find_library("EGL") is None
    else:
        missing = not (environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"))
    if missing:
        raise GlBackendError(f"--gl {gl}: {GL_MISSING[gl]}: {GL_REMEDIES[gl]}")


def gl_environment(gl: str, environ: dict[str, str] | os._Environ[str] = os.environ
                   ) -> dict[str, str]:
    """The environment of the rendering process: ``environ`` with ``MUJOCO_GL`` and
    ``PYOPENGL_PLATFORM`` set for ``gl`` (PyOpenGL must agree with MuJoCo's context;
    GLFW uses PyOpenGL's default platform, so the variable is removed for it)."""
    env = dict(environ)
    env["MUJOCO_GL"] = gl
    if gl == "glfw":
        env.pop("PYOPENGL_PLATFORM", None)
    else:
        env["PYOPENGL_PLATFORM"] = gl
    return env


# ----------------------------------------------------------------------- rendering


class ChaseRenderer:
    """Renders the logged car from the chase camera (needs a working GL back-end).

    Use as a context manager; the process must have imported ``mujoco`` with ``MUJOCO_GL``
    set to ``gl`` (see the module docstring), which :func:`render_log` arranges.
    """

    def __init__(self, scene: LoggedScene, width: int, height: int, gl: str) -> None:
        check_gl_backend(gl)
        mujoco = _import_mujoco(gl)
        self._mujoco = mujoco
        model = _compile_for_video(mujoco, scene)
        _apply_render_settings(model, width, height)
        self._model = model
        self._data = mujoco.MjData(model)
        self._scene = scene
        self._lookup(model)
        path = scene.path_xy_m
        self._segments = path_segments(path) if path is not None and len(path) > 1 else None
        max_geom = model.ngeom + 100 + (0 if self._segments is None else len(self._segments[1]))
        try:
            self._renderer = mujoco.Renderer(model, height=height, width=width,
                                             max_geom=max_geom)
        except Exception as error:  # noqa: BLE001 - GL failures come as many types
            message = str(error).strip().splitlines()[0] if str(error).strip() else \
                type(error).__name__
            raise GlBackendError(f"MUJOCO_GL={gl}: cannot create an OpenGL context "
                                 f"({message}): {GL_REMEDIES[gl]}") from None
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self._heading = smoothed_heading(scene.truth.t_s, scene.truth.yaw_rad)

    def _lookup(self, model: mujoco.MjModel) -> None:
        """qpos addresses of the free joint and the steer hinges; wheelbase and track from
        the wheel bodies (for the Ackermann split of the logged steering angle)."""
        mujoco = self._mujoco

        def joint(name: str) -> int:
            index = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if index < 0:
                raise RenderError(f"the logged MJCF has no joint named {name!r}")
            return int(model.jnt_qposadr[index])

        def body_pos(name: str) -> np.ndarray:
            index = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
            if index < 0:
                raise RenderError(f"the logged MJCF has no body named {name!r}")
            return np.array(model.body_pos[index])

        self._free_qpos = joint("chassis_free")
        self._traffic_mocap = {}
        for name in self._scene.traffic:
            body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"car_{name}/")
            if body >= 0 and model.body_mocapid[body] >= 0:
                self._traffic_mocap[name] = int(model.body_mocapid[body])
        self._steer_qpos = (joint("front_left_steer"), joint("front_right_steer"))
        front_left, rear_left = body_pos("front_left_wheel"), body_pos("rear_left_wheel")
        front_right = body_pos("front_right_wheel")
        self._wheelbase_m = float(front_left[0] - rear_left[0])
        self._track_m = float(front_left[1] - front_right[1])

    def __enter__(self) -> ChaseRenderer:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Free the GL context now (not at interpreter exit, where EGL's teardown fails)."""
        self._renderer.close()

    def frame(self, t_s: float) -> np.ndarray:
        """The picture at log time ``t_s``: height x width x 3, uint8 RGB."""
        from cosim.plant.sedan_model import ackermann_angles

        mujoco, model, data = self._mujoco, self._model, self._data
        pose = self._scene.truth.at(t_s)
        a = self._free_qpos
        data.qpos[a:a + 3] = (pose.x_m, pose.y_m, pose.z_m)
        data.qpos[a + 3:a + 7] = quaternion_zyx(pose.yaw_rad, pose.pitch_rad, pose.roll_rad)
        left, right = ackermann_angles(pose.steer_rad, self._wheelbase_m, self._track_m)
        data.qpos[self._steer_qpos[0]] = left
        data.qpos[self._steer_qpos[1]] = right
        for name, slot in self._traffic_mocap.items():
            track = self._scene.traffic[name]
            x, y, yaw = (float(np.interp(t_s, track[:, 0], track[:, i])) for i in (1, 2, 3))
            data.mocap_pos[slot] = (x, y, 0.0)
            data.mocap_quat[slot] = (math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw))
        mujoco.mj_forward(model, data)

        heading = float(np.interp(t_s, self._scene.truth.t_s, self._heading))
        view = chase_camera(pose.x_m, pose.y_m, heading)
        camera = self._camera
        camera.lookat[:] = view.lookat_m
        camera.distance = view.distance_m
        camera.azimuth = view.azimuth_deg
        camera.elevation = view.elevation_deg
        renderer = self._renderer
        renderer.update_scene(data, camera)
        scene = renderer.scene
        scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
        if self._segments is not None:
            self._add_path(scene, pose.x_m, pose.y_m)
        return renderer.render()

    def _add_path(self, scene: mujoco.MjvScene, x_m: float, y_m: float) -> None:
        """Paint the path segments near the car onto the ground (decor geoms)."""
        mujoco = self._mujoco
        centres, half_lengths, headings = self._segments  # type: ignore[misc]
        near = np.hypot(centres[:, 0] - x_m, centres[:, 1] - y_m) < PATH_DRAW_RADIUS_M
        rgba = np.array(PATH_RGBA, dtype=np.float32)
        for (cx, cy), half, yaw in zip(centres[near], half_lengths[near], headings[near],
                                        strict=True):
            if scene.ngeom >= scene.maxgeom:
                break
            c, s = math.cos(yaw), math.sin(yaw)
            geom = scene.geoms[scene.ngeom]
            mujoco.mjv_initGeom(
                geom, mujoco.mjtGeom.mjGEOM_BOX,
                np.array([half + 0.02, PATH_HALF_WIDTH_M, PATH_HEIGHT_M]),
                np.array([cx, cy, PATH_HEIGHT_M]),
                np.array([c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0]), rgba)
            geom.emission = 0.4
            geom.category = mujoco.mjtCatBit.mjCAT_DECOR
            scene.ngeom += 1


def _import_mujoco(gl: str) -> Any:
    """``mujoco``, checking that this process imported it for ``gl``."""
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    if requested != gl:
        raise GlBackendError(f"MUJOCO_GL={requested or '(unset)'} in this process, but "
                             f"rendering with {gl} needs MUJOCO_GL={gl} before mujoco is "
                             "imported (use cosim.plots.render.render_log)")
    try:
        import mujoco
    except Exception as error:  # noqa: BLE001 - a broken GL stack fails in many ways
        raise GlBackendError(f"MUJOCO_GL={gl}: importing mujoco failed ({error}): "
                             f"{GL_REMEDIES[gl]}") from None
    return mujoco


def _compile_for_video(mujoco: Any, scene: LoggedScene) -> mujoco.MjModel:
    """The logged MJCF compiled with a sky added (the sedan's model has none, and a black
    sky looks like a broken render). Through ``MjSpec``, so the logged XML stays as it was."""
    try:
        spec = mujoco.MjSpec.from_string(scene.mjcf_xml, assets=scene.assets)
        if not any(t.type == mujoco.mjtTexture.mjTEXTURE_SKYBOX for t in spec.textures):
            spec.add_texture(name="video_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                             builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=SKY_RGB,
                             rgb2=SKY_HORIZON_RGB, width=256, height=256)
        return spec.compile()
    except ValueError as error:
        raise RenderError(f"the logged MJCF ({scene.model_source}) does not compile: "
                          f"{str(error).strip().splitlines()[0]}") from None


def _apply_render_settings(model: mujoco.MjModel, width: int, height: int) -> None:
    """Visual settings of the video (they change drawing only, never the model's physics):
    an offscreen buffer as big as the frame, no multisampling (a software renderer's cost
    for little gain at video sizes), a far plane beyond the haze."""
    visual = model.vis
    visual.global_.offwidth = max(int(visual.global_.offwidth), width)
    visual.global_.offheight = max(int(visual.global_.offheight), height)
    visual.quality.offsamples = 0
    visual.map.zfar = VISIBILITY_M / max(float(model.stat.extent), 1e-6)


def render_video_here(log_path: Path | str, out_path: Path | str, options: RenderOptions,
                      progress: Callable[[float], None] | None = None) -> RenderResult:
    """Render ``log_path`` to ``out_path`` in this process (``MUJOCO_GL`` must already be the
    back-end, before ``mujoco`` was imported: :func:`render_log` is the safe entry)."""
    options.validate()
    gl = options.gl or default_gl()
    started = time.perf_counter()
    scene = read_logged_scene(log_path)
    times = frame_times(scene.truth.t_s, options.fps, options.start_s, options.duration_s)
    out_path = Path(out_path)
    partial = _partial_path(out_path)
    render_s = 0.0
    with ChaseRenderer(scene, options.width, options.height, gl) as renderer:
        writer = _open_video(partial, options)
        try:
            for k, t in enumerate(times):
                tick = time.perf_counter()
                pixels = renderer.frame(float(t))
                render_s += time.perf_counter() - tick
                writer.send(np.ascontiguousarray(pixels))
                if progress is not None:
                    progress((k + 1) / len(times))
            writer.close()
        except BaseException:
            writer.close()
            partial.unlink(missing_ok=True)
            raise
    partial.replace(out_path)
    return RenderResult(out_path, len(times), options.fps, options.width, options.height, gl,
                        scene.model_source, render_s / len(times),
                        time.perf_counter() - started)


def _partial_path(out_path: Path) -> Path:
    """Where the video is written until it is complete (same suffix: ffmpeg picks the
    container from it)."""
    return out_path.with_name(f"{out_path.stem}.partial{out_path.suffix}")


def _open_video(path: Path, options: RenderOptions) -> Any:
    """A started ``imageio_ffmpeg.write_frames`` generator: send RGB frames, then close."""
    try:
        import imageio_ffmpeg
    except ImportError:
        raise RenderError("imageio-ffmpeg is not installed (pip install imageio-ffmpeg)"
                          ) from None
    try:
        writer = imageio_ffmpeg.write_frames(
            str(path), (options.width, options.height), fps=options.fps, codec="libx264",
            pix_fmt_in="rgb24", pix_fmt_out="yuv420p", quality=None, macro_block_size=2,
            ffmpeg_log_level="error",
            output_params=["-crf", str(VIDEO_CRF), "-preset", "fast",
                           "-movflags", "+faststart"])
        writer.send(None)  # starts ffmpeg
    except (OSError, RuntimeError) as error:
        raise RenderError(f"cannot start ffmpeg for {str(path)!r}: {error}") from None
    return writer


# ------------------------------------------------- the child process and its caller


def check_video_path(out_path: Path | str, option: str = "--out") -> None:
    """Raise :class:`RenderError` unless ``out_path`` is a video name in an existing
    directory (checked before a run, so ``cosim run --video`` fails before simulating)."""
    out_path = Path(out_path)
    if out_path.suffix.lower() not in VIDEO_SUFFIXES:
        raise RenderError(f"{option} {str(out_path)!r}: expected a video file ending with "
                          f"{', '.join(VIDEO_SUFFIXES)}")
    if not out_path.parent.is_dir():
        raise RenderError(f"{option} {str(out_path)!r}: the directory "
                          f"{str(out_path.parent)!r} does not exist")


def render_log(log_path: Path | str, out_path: Path | str,
               options: RenderOptions = RenderOptions(),
               progress: Callable[[float], None] | None = None) -> RenderResult:
    """Render a log to a video in a child process with the GL back-end set up for it.

    ``progress`` gets the finished fraction after each frame. Raises :class:`RenderError`
    (bad option, unreadable log, encoder failure) or :class:`GlBackendError` (back-end
    missing) with the child's one-line message.
    """
    options.validate()
    log_path, out_path = Path(log_path), Path(out_path)
    if not log_path.is_file():
        raise RenderError(f"{str(log_path)!r}: no such file (expected an MCAP log)")
    check_video_path(out_path)
    gl = options.gl or default_gl()
    check_gl_backend(gl)
    request = {"log": str(log_path), "out": str(out_path),
               "options": dataclasses.asdict(dataclasses.replace(options, gl=gl))}
    command = [sys.executable, "-m", "cosim.plots.render", json.dumps(request)]
    result: dict[str, Any] | None = None
    with tempfile.TemporaryFile(mode="w+") as stderr:
        child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=stderr, text=True,
                                 env=gl_environment(gl))
        try:
            assert child.stdout is not None
            for line in child.stdout:
                try:
                    message = json.loads(line)
                except ValueError:  # a library's chatter on stdout, not the protocol
                    continue
                if not isinstance(message, dict):
                    continue
                if "progress" in message and progress is not None:
                    progress(float(message["progress"]))
                elif "result" in message:
                    result = message["result"]
            code = child.wait()
        except BaseException:  # an interrupt (the child got it too) or a failed callback
            if child.poll() is None:
                child.terminate()
            child.wait()
            _partial_path(out_path).unlink(missing_ok=True)
            raise
        stderr.seek(0)
        lines = [line for line in stderr.read().splitlines() if line.strip()]
    if code == 0 and result is not None:
        return RenderResult(**{**result, "path": Path(result["path"])})
    last = lines[-1] if lines else f"exit code {code}"
    if code == _CHILD_GL_ERROR:
        raise GlBackendError(last)
    if code == _CHILD_USAGE_ERROR:
        raise RenderError(last)
    raise RenderError(f"the renderer process failed (exit {code}): {last}")


def render_for_cli(log_path: Path | str, out_path: Path | str | None,
                   options: RenderOptions) -> RenderResult:
    """:func:`render_log` for the command line: ``out_path`` None is the log's name with
    ``.mp4``; a progress bar on a terminal."""
    out = Path(log_path).with_suffix(".mp4") if out_path is None else Path(out_path)
    if not sys.stderr.isatty():
        return render_log(log_path, out, options)
    from rich.progress import Progress

    with Progress(transient=True) as bar:
        task = bar.add_task(f"render {out.name}", total=1.0)
        return render_log(log_path, out, options,
                          lambda done: bar.update(task, completed=done))


def describe(result: RenderResult) -> str:
    """One line about a finished video, for the command line."""
    return (f"video: {result.path}  {result.frames} frames at {result.fps:g} fps, "
            f"{result.width}x{result.height}, {result.size_bytes / 1e6:.2f} MB; "
            f"{1e3 * result.render_s_per_frame:.1f} ms/frame ({result.gl}), "
            f"{result.wall_time_s:.1f} s in all")


_CHILD_USAGE_ERROR = 2
_CHILD_GL_ERROR = 3


def main(argv: Sequence[str] | None = None) -> int:
    """The child process of :func:`render_log`: ``python -m cosim.plots.render REQUEST_JSON``.

    Prints ``{"progress": f}`` lines and one ``{"result": {...}}`` line on stdout; a
    :class:`CosimError` is one line on stderr and exit code 2 (3 for a GL back-end error).
    """
    args = list(sys.argv[1:] if argv is None else argv)
    try:
        if len(args) != 1:
            raise RenderError("usage: python -m cosim.plots.render REQUEST_JSON (internal: use "
                              "`cosim render`)")
        request = json.loads(args[0])
        options = RenderOptions(**request["options"])

        def report(done: float) -> None:
            print(json.dumps({"progress": round(done, 4)}), flush=True)

        result = render_video_here(request["log"], request["out"], options, report)
    except GlBackendError as error:
        print(error, file=sys.stderr)
        return _CHILD_GL_ERROR
    except CosimError as error:
        print(error, file=sys.stderr)
        return _CHILD_USAGE_ERROR
    print(json.dumps({"result": result.to_dict()}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
