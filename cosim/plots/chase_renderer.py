"""Draws the logged car from the chase camera with MuJoCo's offscreen renderer.

The scene is the logged MJCF (with a sky added, through ``MjSpec``, so the logged XML stays
as it was); the car is posed from the truth (free joint from position, yaw, pitch, roll;
front wheels at their Ackermann angles of the logged steering angle) and only placed by
``mj_forward``: nothing is simulated. The reference path is painted on the ground as thin
flat boxes added to the renderer's scene after ``update_scene`` (``mjv_initGeom``): drawn,
never part of the model.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from cosim.core.exceptions import GlBackendError, RenderError
from cosim.core.rotations import quaternion_zyx
from cosim.plots.gl_backend import GL_REMEDIES, check_gl_backend, import_mujoco
from cosim.plots.video_scene import LoggedScene, chase_camera, path_segments, smoothed_heading

if TYPE_CHECKING:
    import mujoco

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


class ChaseRenderer:
    """Renders the logged car from the chase camera (needs a working GL back-end).

    Use as a context manager; the process must have imported ``mujoco`` with ``MUJOCO_GL``
    set to ``gl`` (see the module docstring), which :func:`render_log` arranges.
    """

    def __init__(self, scene: LoggedScene, width: int, height: int, gl: str) -> None:
        check_gl_backend(gl)
        mujoco = import_mujoco(gl)
        self._mujoco = mujoco
        model = compile_for_video(mujoco, scene)
        apply_render_settings(model, width, height)
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


def compile_for_video(mujoco: Any, scene: LoggedScene) -> mujoco.MjModel:
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


def apply_render_settings(model: mujoco.MjModel, width: int, height: int) -> None:
    """Visual settings of the video (they change drawing only, never the model's physics):
    an offscreen buffer as big as the frame, no multisampling (a software renderer's cost
    for little gain at video sizes), a far plane beyond the haze."""
    visual = model.vis
    visual.global_.offwidth = max(int(visual.global_.offwidth), width)
    visual.global_.offheight = max(int(visual.global_.offheight), height)
    visual.quality.offsamples = 0
    visual.map.zfar = VISIBILITY_M / max(float(model.stat.extent), 1e-6)
