"""``cosim plot`` and ``cosim render``: figures and a video of a log."""

from __future__ import annotations

import argparse
from typing import Any

from cosim.cli.common import Handler


def add_parsers(commands: Any) -> dict[str, Handler]:
    plot = commands.add_parser("plot", help="PNG figures of a log (or up to six logs overlaid)")
    plot.add_argument("files", metavar="FILE.mcap", nargs="+",
                      help="a log, or several (up to 6) to overlay")
    plot.add_argument("--out", metavar="DIR",
                      help="output directory (default <log>-plots beside the log)")
    plot.add_argument("--label", action="append", default=[], metavar="TEXT",
                      help="name a log in the legends, once per log in their order "
                           "(default: what differs in their configurations)")
    render = commands.add_parser(
        "render", help="render a log to a video from a chase camera (MuJoCo, offscreen)")
    render.add_argument("file", metavar="FILE.mcap")
    render.add_argument("--out", metavar="VIDEO.mp4",
                        help="video file (default: beside the log, logs/x.mcap -> logs/x.mp4)")
    render.add_argument("--fps", type=float, default=30.0, metavar="N",
                        help="frames per second (default 30)")
    render.add_argument("--width", type=int, default=640, metavar="W", help="pixels (640)")
    render.add_argument("--height", type=int, default=360, metavar="H", help="pixels (360)")
    render.add_argument("--start", type=float, default=0.0, metavar="S",
                        help="first frame at S seconds into the log")
    render.add_argument("--duration", type=float, metavar="S", help="seconds of video")
    render.add_argument("--gl", choices=("osmesa", "egl", "glfw"),
                        help="OpenGL back-end (default MUJOCO_GL, else osmesa: software)")
    return {"plot": plot_command, "render": render_command}


def plot_command(args: argparse.Namespace) -> int:
    from cosim.plots import plot_command

    return plot_command(args.files, args.out, args.label)


def render_command(args: argparse.Namespace) -> int:
    from cosim.plots.render import RenderOptions, describe, render_for_cli

    options = RenderOptions(args.fps, args.width, args.height, args.start, args.duration,
                            args.gl)
    print(describe(render_for_cli(args.file, args.out, options)))
    return 0
