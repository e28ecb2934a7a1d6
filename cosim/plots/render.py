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
3. **A chase camera follows it** (:func:`~cosim.plots.video_scene.chase_camera`): it looks
   at a point just ahead of the car from behind and above, at the car's heading smoothed by
   a first-order lag (:data:`~cosim.plots.video_scene.CHASE_HEADING_TIME_CONSTANT_S`), so a
   lane change swings the car in the frame instead of jerking the whole picture. The
   smoothing runs over the log's truth samples, so the view does not depend on the frame
   rate.
4. **The reference path** (``/reference/path``) is painted on the ground as thin flat
   boxes added to the renderer's scene after ``update_scene`` (``mjv_initGeom``): drawn,
   not simulated, and never part of the model.
5. **Frames go to ffmpeg** through a pipe (``imageio_ffmpeg.write_frames``, the ffmpeg
   binary that the ``imageio-ffmpeg`` wheel ships): H.264 (libx264), yuv420p, which every
   player opens. The video is written to a ``.partial`` file and renamed when complete.

Frame ``k`` shows the car at ``start + k / fps`` (seconds since the log's first truth
sample), for every such time up to the end of the log or of ``--duration``.

The modules: :mod:`cosim.plots.video_scene` (steps 1-3: what the log holds, the frame
times, the chase camera), :mod:`cosim.plots.chase_renderer` (drawing), this module (options,
the child process, encoding) and :mod:`cosim.plots.gl_backend` (below).

**The OpenGL back-end.** MuJoCo picks how it gets an OpenGL context from the ``MUJOCO_GL``
environment variable, once, when ``mujoco`` is first imported; the plant imports it with
``MUJOCO_GL=disable`` (the Makefile's setting; no context needed to simulate). So
:func:`render_log` runs the renderer in a child process (``python -m cosim.plots.render``,
private protocol: one JSON request in argv, JSON lines of progress and result on stdout)
whose environment sets ``MUJOCO_GL`` and ``PyOpenGL``'s ``PYOPENGL_PLATFORM`` to the chosen
back-end; the caller may have imported ``mujoco`` any way it liked. Back-ends
(:data:`~cosim.plots.gl_backend.GL_BACKENDS`): ``osmesa`` renders in software on any CPU
(the default unless ``MUJOCO_GL`` names another one; Debian/Ubuntu package
``libosmesa6``), ``egl`` renders headless on a GPU (``libegl1`` and the GPU's driver),
``glfw`` needs a display. A missing
back-end is a :class:`~cosim.core.exceptions.GlBackendError` naming the package to install.

Software rendering (OSMesa's llvmpipe) costs about 12 ms per 640x360 frame and 27 ms per
1280x720 one; MuJoCo's shadow map would cost five times that, so shadows and multisampling
are off (the sun still shades the faces).

Traffic cars (``car_<name>/`` mocap bodies of the attached MJCF) are posed from
``/traffic/cars``, interpolated like the ego. Not drawn yet: wheel spin (the rims are plain
cylinders).
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.core.exceptions import CosimError, GlBackendError, RenderError
from cosim.log.reader import log_file_problem
from cosim.plots.chase_renderer import ChaseRenderer
from cosim.plots.gl_backend import GL_BACKENDS, check_gl_backend, default_gl, gl_environment
from cosim.plots.video_scene import frame_times, read_logged_scene

VIDEO_SUFFIXES: tuple[str, ...] = (".mp4", ".mov", ".mkv")
"""Containers that hold H.264 video; ``--out`` must end with one of them."""

MAX_FRAME_SIZE_PX = 4096
"""Largest ``--width``/``--height`` [px] (MuJoCo's offscreen buffer is made this big)."""

VIDEO_CRF = 23
"""libx264 constant rate factor (0 lossless .. 51 worst; 23 is x264's default)."""


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
    problem = log_file_problem(log_path)
    if problem is not None:
        raise RenderError(f"{str(log_path)!r}: {problem} (expected an MCAP log)")
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
