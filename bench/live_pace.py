"""How a live run keeps pace, as a viewer sees it, and what streaming costs.

    .venv/bin/python bench/live_pace.py [--duration 5] [--pace 1.0] [--repeats 3]

1. Pacing: ``cosim run lane-change --live --pace P`` with a WebSocket client subscribed to
   ``/vehicle/truth``; the wall time between the client receiving the message of simulated
   time 0 and the one of the last step, against ``duration / P``.
   The client joins when it can, so the time is scaled from what it saw (wall seconds per
   simulated second from its first message to the last).
2. Cost: the same run without ``--pace``, with the client subscribed, against a plain run
   (no ``--live``), interleaved; the figure is the run's own ``wall_time_s`` (set-up and
   loop, without the interpreter's start), median of the repeats, and the ratio.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import websockets

SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


async def _watch(port: int, duration_s: float) -> tuple[float, float]:
    """Simulated seconds and wall seconds between the first truth message the client
    received and the last one of the run (only the first message is decoded: the rest are
    timed by their log time, so the client costs the run as little CPU as it can)."""
    deadline = time.monotonic() + 120
    while True:
        try:
            client = await websockets.connect(f"ws://127.0.0.1:{port}",
                                              subprotocols=SUBPROTOCOLS, max_size=None)
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.02)
    first_wall = first_sim = float("nan")
    first_log_ns = 0
    async with client:
        async for frame in client:
            if isinstance(frame, str):
                op = json.loads(frame)
                if op["op"] == "advertise":
                    for channel in op["channels"]:
                        if channel["topic"] == "/vehicle/truth":
                            await client.send(json.dumps({"op": "subscribe", "subscriptions": [
                                {"id": 1, "channelId": channel["id"]}]}))
                continue
            if frame[0] != 1:
                continue
            now = time.perf_counter()
            _, log_time_ns = struct.unpack_from("<IQ", frame, 1)
            if first_log_ns == 0:
                first_wall, first_log_ns = now, log_time_ns
                first_sim = float(json.loads(frame[13:])["t_s"])
            t_s = first_sim + (log_time_ns - first_log_ns) * 1e-9
            if t_s >= duration_s - 1e-6:
                return duration_s - first_sim, now - first_wall
    raise SystemExit("the run ended before its last truth message reached the client")


def _run(args: list[str], out: Path, port: int | None, watch_s: float | None
         ) -> tuple[float, float]:
    """(wall_time_s metric, viewer's first-to-last seconds or NaN)."""
    command = [sys.executable, "-m", "cosim.cli", "run", "lane-change", *args, "--json",
               "--force", "--out", str(out)]
    env = {**os.environ, "MUJOCO_GL": "disable"}
    process = subprocess.Popen(command, env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.DEVNULL)
    seen = float("nan")
    if port is not None and watch_s is not None:
        sim_s, wall_s = asyncio.run(_watch(port, watch_s))
        seen = wall_s / sim_s  # wall seconds per simulated second, as the viewer saw it
    stdout, _ = process.communicate(timeout=600)
    if process.returncode != 0:
        raise SystemExit(f"run failed: {' '.join(command)}")
    return float(json.loads(stdout)["metrics"]["wall_time_s"]), seen


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--pace", type=float, default=1.0)
    parser.add_argument("--repeats", type=int, default=3)
    options = parser.parse_args()
    duration = ["--duration", f"{options.duration:g}"]
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "run.mcap"
        paced = []
        for _ in range(options.repeats):
            port = _free_port()
            _, seen = _run([*duration, "--live", "--port", str(port), "--pace",
                            f"{options.pace:g}"], out, port, options.duration)
            paced.append(seen)
        seen = statistics.median(paced) * options.duration
        target = options.duration / options.pace
        print(f"pacing: {options.duration:g} s run at --pace {options.pace:g}: the viewer saw "
              f"it take {seen:.3f} s (median of {options.repeats}, wall per simulated second "
              f"{', '.join(f'{p:.4f}' for p in paced)}); target {target:.3f} s; error "
              f"{100 * (seen / target - 1):+.2f} %")
        plain, live = [], []
        for _ in range(options.repeats):
            plain.append(_run(duration, out, None, None)[0])
            port = _free_port()
            live.append(_run([*duration, "--live", "--port", str(port)], out, port,
                             options.duration)[0])
        ratios = [b / a for a, b in zip(plain, live, strict=True)]
        print(f"cost: wall_time_s plain {statistics.median(plain):.3f} s, live with a "
              f"subscribed client {statistics.median(live):.3f} s (medians of "
              f"{options.repeats}, interleaved); live/plain per pair median "
              f"{statistics.median(ratios):.3f} ({', '.join(f'{r:.3f}' for r in ratios)})")


if __name__ == "__main__":
    main()
