"""`cosim render`: the chase-camera video of a log (cosim.plots.render).

The geometry and timing tests need no OpenGL. The video tests render the session's short
lane change in software (OSMesa; `.ci/run` installs libosmesa6) and read the MP4 back with
the ffmpeg that imageio-ffmpeg ships: frame count, not blank, the car moves, the car is in
the middle of the picture and the amber reference path is drawn.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cosim.cli import main
from cosim.core.exceptions import GlBackendError, RenderError
from cosim.plots import gl_backend, render, video_scene
from cosim.plots.render import RenderOptions
from cosim.simulation.runner import RunResult

WIDTH, HEIGHT = 480, 270


def _osmesa_missing() -> str | None:
    try:
        gl_backend.check_gl_backend("osmesa")
    except GlBackendError as error:
        return str(error)
    return None


needs_osmesa = pytest.mark.skipif(
    _osmesa_missing() is not None,
    reason=f"no software OpenGL: {_osmesa_missing()} (.ci/run installs it)")


def _read_video(path: Path) -> tuple[dict, np.ndarray]:
    """(metadata, frames as N x H x W x 3 uint8) of a video file."""
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    width, height = meta["size"]
    frames = [np.frombuffer(f, np.uint8).reshape(height, width, 3) for f in reader]
    return meta, np.stack(frames)


# ----------------------------------------------------------- no OpenGL needed


def test_frame_times_cover_the_log_at_the_frame_rate() -> None:
    truth_t = np.arange(0.0, 2.0 + 1e-9, 0.01)  # 2 s at 100 Hz
    times = video_scene.frame_times(truth_t, fps=30.0)
    assert len(times) == 61  # 0, 1/30, ..., 60/30 = 2.0
    assert times[0] == 0.0 and math.isclose(times[-1], 2.0)
    window = video_scene.frame_times(truth_t, fps=10.0, start_s=0.5, duration_s=1.0)
    assert np.allclose(window, 0.5 + np.arange(11) / 10.0)
    assert len(video_scene.frame_times(truth_t, fps=10.0, start_s=1.5, duration_s=5.0)) == 6
    with pytest.raises(RenderError, match="--start 3"):
        video_scene.frame_times(truth_t, fps=10.0, start_s=3.0)


def test_heading_lag_is_first_order() -> None:
    """A yaw step of 1 rad: after one time constant the camera has turned 1 - 1/e of it."""
    tau = video_scene.CHASE_HEADING_TIME_CONSTANT_S
    t = np.arange(0.0, 5.0 * tau, 0.01)
    yaw = np.where(t > 0.0, 1.0, 0.0)
    heading = video_scene.smoothed_heading(t, yaw, tau)
    assert heading[0] == 0.0
    k = int(round(tau / 0.01))  # sample k has had k updates towards the new yaw
    assert math.isclose(heading[k], 1.0 - math.exp(-1.0), rel_tol=1e-9)


def test_chase_camera_sits_behind_and_above_the_car() -> None:
    for heading in (0.0, 1.0, -2.5):
        view = video_scene.chase_camera(10.0, -4.0, heading)
        az, el = math.radians(view.azimuth_deg), math.radians(view.elevation_deg)
        forward = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az),
                            math.sin(el)])
        camera = np.array(view.lookat_m) - view.distance_m * forward
        behind = (camera[:2] - (10.0, -4.0)) @ (math.cos(heading), math.sin(heading))
        assert behind < -5.0  # metres behind the car along its heading
        assert camera[2] > 2.0


def test_path_segments_join_consecutive_points() -> None:
    points = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 0.0], [2.0, 3.0]])
    centres, half_lengths, headings = video_scene.path_segments(points)
    assert np.allclose(centres, [[1.0, 0.0], [2.0, 1.5]])  # the repeated point is dropped
    assert np.allclose(half_lengths, [1.0, 1.5])
    assert np.allclose(headings, [0.0, math.pi / 2])


def test_missing_back_end_names_the_package_to_install() -> None:
    with pytest.raises(GlBackendError, match=r"apt-get install libosmesa6"):
        gl_backend.check_gl_backend("osmesa", find_library=lambda name: None)
    with pytest.raises(GlBackendError, match=r"apt-get install libegl1"):
        gl_backend.check_gl_backend("egl", find_library=lambda name: None)
    with pytest.raises(GlBackendError, match=r"needs a display.*--gl osmesa"):
        gl_backend.check_gl_backend("glfw", environ={})
    gl_backend.check_gl_backend("glfw", environ={"DISPLAY": ":0"})


def test_back_end_choice_and_child_environment() -> None:
    assert gl_backend.default_gl({}) == "osmesa"
    assert gl_backend.default_gl({"MUJOCO_GL": "disable"}) == "osmesa"
    assert gl_backend.default_gl({"MUJOCO_GL": "EGL"}) == "egl"
    env = gl_backend.gl_environment("osmesa", {"MUJOCO_GL": "disable", "PYOPENGL_PLATFORM": "egl"})
    assert env["MUJOCO_GL"] == "osmesa" and env["PYOPENGL_PLATFORM"] == "osmesa"
    assert "PYOPENGL_PLATFORM" not in gl_backend.gl_environment("glfw", {"PYOPENGL_PLATFORM": "x"})


@pytest.mark.parametrize(("options", "message"), [
    (RenderOptions(fps=0.0), "--fps 0.0"),
    (RenderOptions(width=641), "--width 641"),
    (RenderOptions(height=8), "--height 8"),
    (RenderOptions(start_s=-1.0), "--start -1.0"),
    (RenderOptions(duration_s=math.nan), "--duration nan"),
    (RenderOptions(gl="glx"), "--gl 'glx'"),
])
def test_bad_options_are_refused(options: RenderOptions, message: str) -> None:
    with pytest.raises(RenderError, match=message.replace(".", r"\.")):
        options.validate()


def test_scene_comes_from_the_log(short_run: RunResult, monkeypatch: pytest.MonkeyPatch
                                  ) -> None:
    import mujoco

    scene = video_scene.read_logged_scene(short_run.log_path)
    assert scene.model_source == "attachment sedan.xml"
    assert len(scene.truth.t_s) == 201 and math.isclose(scene.truth.duration_s, 2.0)
    assert scene.truth.at(1.0).x_m > 10.0  # 15 m/s for a second
    assert scene.path_xy_m is not None and scene.path_xy_m.shape[1] == 2
    # A log without the attachment: the model is rebuilt from the logged config.
    monkeypatch.setattr("cosim.log.reader.read_attachment", lambda path, name: None)
    rebuilt = video_scene.read_logged_scene(short_run.log_path)
    assert rebuilt.model_source == "rebuilt from the config"
    assert rebuilt.mjcf_xml == scene.mjcf_xml
    mujoco.MjModel.from_xml_string(rebuilt.mjcf_xml, rebuilt.assets)


def test_cli_refuses_bad_input_in_one_line(short_run: RunResult, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    log = str(short_run.log_path)
    for argv, expected in [
        (["render", log, "--out", str(tmp_path / "v.gif")], "expected a video file"),
        (["render", log, "--out", str(tmp_path / "no" / "v.mp4")], "does not exist"),
        (["render", str(tmp_path / "none.mcap")], "no such file"),
        (["render", log, "--width", "333"], "--width 333"),
        (["run", "lane-change", "--video", str(tmp_path / "v.avi")], "--video"),
    ]:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert expected in err and err.count("\n") == 1, err
    assert not list(tmp_path.iterdir())


def test_cli_glfw_without_a_display(short_run: RunResult, tmp_path: Path,
                                    monkeypatch: pytest.MonkeyPatch,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    out = tmp_path / "v.mp4"
    assert main(["render", str(short_run.log_path), "--out", str(out), "--gl", "glfw"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("cosim: error: --gl glfw: GLFW needs a display")
    assert err.count("\n") == 1 and not out.exists()


def test_cli_broken_egl_is_one_line(short_run: RunResult, tmp_path: Path,
                                    monkeypatch: pytest.MonkeyPatch,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    """EGL that cannot start (glvnd pointed at no vendor library, or libEGL missing): the
    child process's failure comes back as one line with the remedy, exit code 2."""
    monkeypatch.setenv("__EGL_VENDOR_LIBRARY_FILENAMES", str(tmp_path / "no-vendor.json"))
    out = tmp_path / "v.mp4"
    code = main(["render", str(short_run.log_path), "--out", str(out), "--gl", "egl",
                 "--duration", "0.1"])
    err = capsys.readouterr().err
    if code == 0:
        pytest.skip("this EGL does not load its driver through glvnd's vendor files")
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith("cosim: error: ") and "apt-get install libegl1" in err
    assert "Traceback" not in err and not out.exists()


# ---------------------------------------------------------------- videos


@needs_osmesa
def test_video_of_a_short_run(short_run: RunResult, tmp_path: Path) -> None:
    out = tmp_path / "short.mp4"
    options = RenderOptions(fps=15.0, width=WIDTH, height=HEIGHT, gl="osmesa")
    result = render.render_log(short_run.log_path, out, options)
    assert result.frames == 31 and result.path == out and out.stat().st_size > 10_000
    assert result.model_source == "attachment sedan.xml"
    assert not list(tmp_path.glob("*.partial*"))

    meta, frames = _read_video(out)
    assert meta["codec"] == "h264" and meta["pix_fmt"].startswith("yuv420p")
    assert meta["size"] == (WIDTH, HEIGHT) and math.isclose(meta["fps"], 15.0)
    assert frames.shape == (31, HEIGHT, WIDTH, 3)
    assert all(frame.std() > 20.0 for frame in frames)  # sky, ground, car: not blank
    # The car moves 30 m in 2 s, so the chequered ground slides under the camera.
    steps = [np.abs(frames[k + 1].astype(int) - frames[k]).mean() for k in range(30)]
    assert min(steps) > 0.5
    # The red car is in the middle of the picture; the amber path is painted on the ground.
    r, g, b = (frames[..., c].astype(int) for c in range(3))
    red = (r > 110) & (g < 60) & (b < 60)
    amber = (r > 170) & (g > 120) & (b < 90)
    middle = red[:, int(0.45 * HEIGHT):int(0.9 * HEIGHT), int(0.35 * WIDTH):int(0.65 * WIDTH)]
    assert middle.mean(axis=(1, 2)).min() > 0.05
    assert red[:, :, :int(0.25 * WIDTH)].mean() < 0.005  # and not at the sides
    assert amber.sum(axis=(1, 2)).min() > 30


@needs_osmesa
def test_video_window_and_cosim_run_video(short_run: RunResult, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "window.mp4"
    assert main(["render", str(short_run.log_path), "--out", str(out), "--fps", "10",
                 "--start", "0.5", "--duration", "1", "--width", "160", "--height", "90"]) == 0
    assert "11 frames at 10 fps, 160x90" in capsys.readouterr().out
    _, frames = _read_video(out)
    assert frames.shape == (11, 90, 160, 3)

    log, video = tmp_path / "run.mcap", tmp_path / "run.mp4"
    assert main(["run", "lane-change", "--duration", "0.5", "--out", str(log),
                 "--video", str(video)]) == 0
    assert f"video: {video}  16 frames at 30 fps, 640x360" in capsys.readouterr().out
    assert _read_video(video)[1].shape == (16, 360, 640, 3)


@needs_osmesa
def test_the_video_goes_beside_the_log_by_default(short_run: RunResult, tmp_path: Path) -> None:
    """Not into the working directory: logs/x.mcap -> logs/x.mp4."""
    import shutil
    import subprocess
    import sys

    logs = tmp_path / "logs"
    logs.mkdir()
    log = shutil.copy(short_run.log_path, logs / "x.mcap")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    cosim = str(Path(sys.executable).with_name("cosim"))
    result = subprocess.run([cosim, "render", str(log), "--duration", "0.2", "--width", "160",
                             "--height", "90"], cwd=elsewhere, capture_output=True, text=True,
                            timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert (logs / "x.mp4").is_file()
    assert list(elsewhere.iterdir()) == []
