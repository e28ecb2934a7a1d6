"""``cosim run --live``: the log's topics streamed over the Foxglove WebSocket protocol.

A real client (the ``websockets`` package) talks to the real server (``foxglove-sdk``) of a
real run: it reads the advertisement, subscribes, decodes the messages with the advertised
JSON Schemas and checks them against the log the same run wrote.
"""

from __future__ import annotations

import asyncio
import json
import os
import signal
import socket
import struct
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jsonschema
import pytest
import websockets

from cosim.log.live import LATCHED_TOPICS, LiveOptions, LiveStream
from cosim.log.reader import iter_messages
from cosim.log.recorder import McapRecorder
from cosim.log.schemas import SCENE_UPDATE, VEHICLE_STATE
from tests.simulation.test_run import _payloads, _strip_wall_clock

SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
"""The protocol's two names, offered as the Foxglove app offers them (the SDK's server
speaks the newer one)."""

MESSAGE_DATA = 0x01
"""Opcode of a binary message-data frame: u32 subscription id, u64 log time, payload."""

CLOSE_TIMEOUT_S = 0.5
"""How long a client that hangs up waits for the server's closing frame before it drops the
connection. The server sends that frame after the messages queued for the client (up to
``cosim.log.live.MESSAGE_BACKLOG``), which a client that has stopped reading never takes:
with websockets' default, 10 s, each test that hangs up early waited those 10 s after it
had what it came for."""


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@dataclass
class Received:
    """What a client saw: advertised channels by topic, decoded messages by topic."""

    channels: dict[str, dict[str, Any]] = field(default_factory=dict)
    messages: dict[str, list[tuple[int, dict[str, Any]]]] = field(default_factory=dict)
    while_running: dict[str, int] = field(default_factory=dict)
    """Messages per topic that arrived while the run's process was still going."""


async def _connect(port: int, deadline_s: float,
                   process: subprocess.Popen[bytes] | None = None) -> Any:
    """Connect, trying again while the server is not up yet; a run's process that has
    ended fails the test at once, with how it ended."""
    while True:
        try:
            return await websockets.connect(f"ws://127.0.0.1:{port}",
                                            subprotocols=SUBPROTOCOLS, max_size=None,
                                            close_timeout=CLOSE_TIMEOUT_S)
        except OSError:
            if process is not None and process.poll() is not None:
                _, err = process.communicate()
                pytest.fail(f"the run ended (exit code {process.returncode}) before a client "
                            f"could connect; its stderr:\n{err.decode()[-2000:]}")
            if time.monotonic() > deadline_s:
                raise
            await asyncio.sleep(0.05)


async def listen(port: int, topics: tuple[str, ...], enough: int,
                 process: subprocess.Popen[bytes] | None = None,
                 timeout_s: float = 240.0) -> Received:
    """Subscribe to ``topics`` and collect messages until each has ``enough`` of them
    (or the server closes), decoding each with its channel's advertised schema.
    ``timeout_s`` covers the run's start, which on a fresh machine compiles the MPC and
    the filter (a minute or more on a loaded machine)."""
    received = Received()
    deadline_s = time.monotonic() + timeout_s
    subscriptions: dict[int, str] = {}
    validators: dict[str, Any] = {}
    async with await _connect(port, deadline_s, process) as client:
        assert client.subprotocol in SUBPROTOCOLS
        while time.monotonic() < deadline_s:
            try:
                frame = await asyncio.wait_for(client.recv(), deadline_s - time.monotonic())
            except websockets.ConnectionClosed:
                break
            if isinstance(frame, str):
                op = json.loads(frame)
                if op["op"] == "advertise":
                    wanted = []
                    for channel in op["channels"]:
                        received.channels[channel["topic"]] = channel
                        if channel["topic"] in topics:
                            sub_id = len(subscriptions) + 1
                            subscriptions[sub_id] = channel["topic"]
                            wanted.append({"id": sub_id, "channelId": channel["id"]})
                    if wanted:
                        await client.send(json.dumps({"op": "subscribe",
                                                      "subscriptions": wanted}))
                continue
            if frame[0] != MESSAGE_DATA:
                continue
            sub_id, log_time_ns = struct.unpack_from("<IQ", frame, 1)
            topic = subscriptions[sub_id]
            channel = received.channels[topic]
            message = json.loads(frame[13:])
            if topic not in validators:  # one validator per channel, its schema checked once
                schema = json.loads(channel["schema"])
                validator_class = jsonschema.validators.validator_for(schema)
                validator_class.check_schema(schema)
                validators[topic] = validator_class(schema)
            validators[topic].validate(message)
            received.messages.setdefault(topic, []).append((log_time_ns, message))
            if process is not None and process.poll() is None:
                received.while_running[topic] = received.while_running.get(topic, 0) + 1
            if all(len(received.messages.get(t, ())) >= enough for t in topics):
                break
    return received


def cosim(*args: str) -> list[str]:
    return [sys.executable, "-m", "cosim.cli", *args]


@pytest.mark.slow
def test_a_live_run_streams_its_log_while_it_runs(tmp_path: Path) -> None:
    port = free_port()
    live_log, plain_log = tmp_path / "live.mcap", tmp_path / "plain.mcap"
    env = {**os.environ, "MUJOCO_GL": "disable"}
    process = subprocess.Popen(
        cosim("run", "lane-change", "--duration", "6", "--live", "--port", str(port),
              "--pace", "2", "--out", str(live_log)),
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        received = asyncio.run(listen(port, ("/vehicle/truth", "/scene/car"), enough=20,
                                      process=process))
    finally:
        out, err = process.communicate(timeout=120)
    assert process.returncode == 0, err.decode()
    assert f"ws://127.0.0.1:{port}" in err.decode()
    assert "already exists" not in err.decode()  # the stream's own latched channels, unsaid
    # Same schemas as the file; messages arrived while the run was going.
    assert received.channels["/vehicle/truth"]["schemaName"] == VEHICLE_STATE["title"]
    assert received.channels["/scene/car"]["schemaName"] == SCENE_UPDATE["title"]
    assert received.channels["/vehicle/truth"]["encoding"] == "json"
    assert received.while_running.get("/vehicle/truth", 0) >= 20
    assert received.while_running.get("/scene/car", 0) >= 20
    # Every topic the shipped Foxglove layout shows is advertised (it works live as on a file).
    assert _layout_topics() <= set(received.channels)
    # Each streamed message is the log's message at the same log time.
    logged = {t: m for t, m in _log_times(live_log, "/vehicle/truth")}
    for log_time_ns, message in received.messages["/vehicle/truth"]:
        assert logged[log_time_ns] == message
    # The log is the one a run without --live writes, apart from wall-clock timing.
    plain = subprocess.run(cosim("run", "lane-change", "--duration", "6", "--out",
                                 str(plain_log)), env=env, capture_output=True, timeout=120)
    assert plain.returncode == 0, plain.stderr.decode()
    live_payloads, plain_payloads = _payloads(live_log), _payloads(plain_log)
    assert live_payloads["/vehicle/truth"] == plain_payloads["/vehicle/truth"]
    assert _strip_wall_clock(live_payloads) == _strip_wall_clock(plain_payloads)


LAYOUT = Path(__file__).resolve().parents[2] / "examples" / "foxglove-layout.json"


def _layout_topics() -> set[str]:
    """The topics the shipped layout's panels read."""
    panels = json.loads(LAYOUT.read_text())["configById"]
    topics = set(panels["3D!car"]["topics"])
    topics.add(panels["Map!gnss"]["followTopic"])
    topics.add(panels["RawMessages!metrics"]["topicPath"].partition(".")[0])
    for panel_id, panel in panels.items():
        if panel_id.startswith("Plot!"):
            topics.update(path["value"].partition(".")[0] for path in panel["paths"])
    return topics


def _log_times(path: Path, topic: str) -> list[tuple[int, dict[str, Any]]]:
    from mcap.reader import make_reader

    with open(path, "rb") as stream:
        return [(message.log_time, json.loads(message.data)) for _, _, message in
                make_reader(stream).iter_messages(topics=[topic])]


def _stream_with(topics: dict[str, dict[str, Any]], tmp_path: Path,
                 options: LiveOptions) -> tuple[LiveStream, McapRecorder]:
    stream = LiveStream(options)
    recorder = McapRecorder(tmp_path / "log.mcap", live=stream)
    for topic, schema in topics.items():
        recorder.register(topic, schema)
    return stream, recorder


def test_a_late_client_gets_the_static_scene_and_the_messages_after_it(
        tmp_path: Path) -> None:
    """The reference path, written once before anyone connected, is sent again to a
    client that subscribes later; ordinary messages come from the subscription on."""
    from cosim.log.schemas import REFERENCE_PATH

    stream, recorder = _stream_with({"/reference/path": REFERENCE_PATH,
                                     "/vehicle/truth": VEHICLE_STATE}, tmp_path,
                                    LiveOptions(port=0))
    path_message = {"s_m": [0.0, 1.0], "x_m": [0.0, 1.0], "y_m": [0.0, 0.0],
                    "yaw_rad": [0.0, 0.0], "curvature_1pm": [0.0, 0.0], "speed_mps": 1.0,
                    "ref_speed_mps": [1.0, 1.0], "closed": False}
    truth = {"t_s": 0.0, "x_m": 1.5}
    with stream, recorder:
        recorder.write("/reference/path", 0.0, path_message)
        recorder.write("/vehicle/truth", 0.0, truth)  # before anyone listens: lost

        async def late_client() -> Received:
            task = asyncio.create_task(listen(stream.port, ("/reference/path",
                                                            "/vehicle/truth"), enough=1,
                                              timeout_s=20))
            for k in range(1, 400):  # the run goes on while the client connects
                await asyncio.sleep(0.005)
                recorder.write("/vehicle/truth", k * 0.01, {**truth, "t_s": k * 0.01})
                if task.done():
                    break
            return await task

        received = asyncio.run(late_client())
    assert "/reference/path" in LATCHED_TOPICS
    ((_, streamed_path),) = received.messages["/reference/path"]
    assert streamed_path == path_message
    assert all(m["t_s"] > 0 for _, m in received.messages["/vehicle/truth"])
    # What was sent again reached the client only: the file has one channel a topic, the path once.
    from mcap.reader import make_reader

    with open(tmp_path / "log.mcap", "rb") as log:
        summary = make_reader(log).get_summary()
    assert summary is not None and summary.statistics is not None
    assert sorted(c.topic for c in summary.channels.values()) == ["/reference/path",
                                                                  "/vehicle/truth"]
    path_id = next(i for i, c in summary.channels.items() if c.topic == "/reference/path")
    assert summary.statistics.channel_message_counts[path_id] == 1


def test_a_busy_port_is_refused_in_one_line_before_the_run(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = subprocess.run(
            cosim("run", "lane-change", "--duration", "1", "--live", "--port", str(port),
                  "--out", str(tmp_path / "x.mcap")),
            env={**os.environ, "MUJOCO_GL": "disable"}, capture_output=True, text=True,
            timeout=120)
    assert done.returncode == 2
    (line,) = done.stderr.strip().splitlines()
    assert f"--port {port}" in line and "Address already in use" in line
    assert not (tmp_path / "x.mcap").exists()


@pytest.mark.parametrize(("args", "expected"), [
    (["--live", "--port", "65536"], "--port 65536: expected a TCP port number in 0..65535"),
    (["--live", "--port", "-1"], "--port -1: expected a TCP port number in 0..65535"),
    (["--live", "--pace", "-2"], "--pace -2.0: expected 0 (as fast as it goes) or a rate"),
    (["--live", "--pace", "inf"], "--pace inf: expected 0 (as fast as it goes) or a rate"),
    (["--live", "--pace", "1e-300"], "--pace 1e-300: expected 0 (as fast as it goes) or a "
     "rate of real time in [0.01, 1000]"),  # was an OverflowError from the wall clock
    (["--live", "--pace", "1e-4"], "in [0.01, 1000]"),  # was deaf to Ctrl-C for minutes
    (["--pace", "1"], "--pace 1.0: only meaningful with --live"),
    (["--port", "9000"], "--port 9000: only meaningful with --live"),
])
def test_bad_live_settings_are_refused(args: list[str], expected: str, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    from cosim.cli import main

    out = tmp_path / "x.mcap"
    assert main(["run", "lane-change", "--duration", "1", "--out", str(out), *args]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert expected in line
    assert not out.exists()


@pytest.mark.parametrize("command", [["sweep", "spec.yaml"], ["compare"]])
def test_sweeps_and_compares_do_not_stream(command: list[str],
                                           capsys: pytest.CaptureFixture[str]) -> None:
    from cosim.cli import main

    assert main([*command, "--live"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "only a single run streams" in line


@pytest.mark.slow
def test_clients_that_come_twice_or_leave_do_not_disturb_the_run(tmp_path: Path) -> None:
    port = free_port()
    log = tmp_path / "run.mcap"
    process = subprocess.Popen(
        # 5 s of wall clock, for two clients that need about 1 s from the command's start (the
        # second reads from 0.2 s of simulated time on with both cores busy elsewhere): a
        # run that ended before the second connects would leave the test saying nothing.
        # (It ran 15 s while each client waited 10 s to hang up: CLOSE_TIMEOUT_S.)
        cosim("run", "lane-change", "--duration", "10", "--live", "--port", str(port),
              "--pace", "2", "--out", str(log)),
        env={**os.environ, "MUJOCO_GL": "disable"}, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE)

    async def two_clients() -> tuple[Received, Received]:
        first = await listen(port, ("/vehicle/truth",), enough=5, process=process)
        # the first has hung up; the second comes while the run goes on
        return first, await listen(port, ("/vehicle/truth",), enough=5, process=process)

    try:
        first, second = asyncio.run(two_clients())
    finally:
        out, err = process.communicate(timeout=120)
    assert process.returncode == 0, err.decode()
    assert first.while_running.get("/vehicle/truth", 0) >= 5
    assert second.while_running.get("/vehicle/truth", 0) >= 5
    metrics = [m for _, m in iter_messages(log, "/metrics")]
    assert metrics[-1]["completed"] is True


@pytest.mark.slow
def test_ctrl_c_with_a_client_connected_keeps_the_log(tmp_path: Path) -> None:
    port = free_port()
    log = tmp_path / "run.mcap"
    process = subprocess.Popen(
        cosim("run", "lane-change", "--duration", "10", "--live", "--port", str(port),
              "--pace", "1", "--out", str(log)),
        env={**os.environ, "MUJOCO_GL": "disable"}, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE)

    async def interrupt_while_listening() -> Received:
        received = await listen(port, ("/vehicle/truth",), enough=10)
        process.send_signal(signal.SIGINT)
        return received

    try:
        received = asyncio.run(interrupt_while_listening())
    finally:
        out, err = process.communicate(timeout=120)
    assert process.returncode == 130, err.decode()
    assert len(received.messages["/vehicle/truth"]) >= 10
    assert "interrupted" in err.decode() and "Traceback" not in err.decode()
    metrics = [m for _, m in iter_messages(log, "/metrics")]
    assert metrics[-1]["completed"] is False
    assert metrics[-1]["sim_duration_s"] < 10


async def _subscribe_and_stall(port: int, process: subprocess.Popen[bytes]) -> None:
    """Subscribe to every channel, then read nothing more until the run's process ends
    (the client's queue holds one frame: the socket fills, the server's backlog with it)."""
    deadline_s = time.monotonic() + 240
    while True:
        try:
            client = await websockets.connect(f"ws://127.0.0.1:{port}",
                                              subprotocols=SUBPROTOCOLS, max_size=None,
                                              max_queue=1)
            break
        except OSError:
            if process.poll() is not None or time.monotonic() > deadline_s:
                pytest.fail("the live run never served")
            await asyncio.sleep(0.05)
    advertised: list[dict[str, Any]] = []
    while not advertised:
        frame = await client.recv()
        if isinstance(frame, str) and json.loads(frame)["op"] == "advertise":
            advertised = json.loads(frame)["channels"]
    await client.send(json.dumps({"op": "subscribe", "subscriptions": [
        {"id": i + 1, "channelId": channel["id"]} for i, channel in enumerate(advertised)]}))
    while process.poll() is None and time.monotonic() < deadline_s:
        await asyncio.sleep(0.1)
    client.transport.abort()


@pytest.mark.slow
def test_a_client_that_stops_reading_does_not_hold_the_command(tmp_path: Path) -> None:
    """Before: the server's stop waited for the client, the metrics came most of a minute
    after the run, with nothing said."""
    port = free_port()
    process = subprocess.Popen(
        cosim("run", "lane-change", "--live", "--port", str(port), "--out",
              str(tmp_path / "stalled.mcap")),
        env={**os.environ, "MUJOCO_GL": "disable"}, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE)
    asyncio.run(_subscribe_and_stall(port, process))
    out, err = process.communicate(timeout=300)
    assert process.returncode == 0, err.decode()
    assert "cte_max_m" in out.decode()
    warning = [line for line in err.decode().splitlines() if "not reading" in line]
    assert len(warning) == 1 and warning[0].startswith("cosim: warning: live: a client")
