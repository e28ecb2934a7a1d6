"""A run streamed to Foxglove while it happens: the log's topics over the Foxglove WebSocket
protocol, optionally paced at a rate of real time.

:class:`LiveStream` is a second sink on the recorder's channels
(:class:`cosim.log.recorder.LiveSink`): Foxglove's own WebSocket server (the ``foxglove-sdk``
package: ``foxglove.start_server``) is started on the recorder's :class:`foxglove.Context`,
so every channel of the log is advertised with its topic, schema name, schema (JSON Schema)
and message encoding (JSON), and every message reaches the file and the clients from the
same ``Channel.log``, with the same bytes and log time (the run's epoch plus its simulated
time, integer nanoseconds). The protocol is the Foxglove WebSocket protocol under the SDK's
subprotocol name ``foxglove.sdk.v1`` (the same messages as ``foxglove.websocket.v1``,
renamed by Foxglove in 2025; the Foxglove app offers both names).

The stream only observes: it never reads or sets anything of the run, so the log and the
simulated car are the same with or without it (``tests/log/test_live.py`` compares the
logs). Pacing sleeps before a message whose simulated time is ahead of the wall clock
scaled by ``pace`` (``pace = 1``: real time; ``0``: no pacing); the wall clock starts at the
first message of simulated time 0, so building the run does not count.

What a client that connects late has missed: the messages written before it subscribed.
The static ones (the reference path and the static scene, written once at the start) are
sent again whenever a client subscribes to them, so Foxglove shows the road whenever it
connects. They go out on channels of the stream's own (the same topics and schemas, marked
:data:`cosim.log.recorder.LIVE_ONLY`), which the file leaves out and the server shows in
place of the log's: a message sent again reaches the clients, never the file. The server
announces the simulated time (``broadcastTime``, capability ``time``) so Foxglove's clock
follows the run.
"""

from __future__ import annotations

import contextlib
import logging
import math
import socket
import threading
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from cosim.core.exceptions import ConfigError
from cosim.log import topics
from cosim.log.recorder import LIVE_ONLY

LATCHED_TOPICS = (topics.REFERENCE_PATH, topics.SCENE)
"""Topics written once at the start: sent again to every client that subscribes later."""

DEFAULT_PORT = 8765
"""Foxglove's default port for a WebSocket connection."""

STOP_WAIT_S = 2.0
"""How long the end of a live run waits for its clients to take what is queued for them."""


class LiveClientStalled(UserWarning):
    """A live client stopped reading: the server was not waited for (:meth:`LiveStream.close`)."""


MESSAGE_BACKLOG = 16384
"""Messages queued per client before the oldest are dropped: about three simulated seconds
of every topic. An unpaced run can outrun a slow client; the log file keeps everything."""

TIME_BROADCAST_PERIOD_NS = 50_000_000
"""How often the server tells clients the simulated time (every 50 ms of simulated time)."""


MIN_PACE = 0.01
"""The slowest pace: a hundredth of real time (a 15 s run in 25 minutes). Slower, one log
period's wait would outlast a user's patience with Ctrl-C, and the wall clock's arithmetic
its range."""

MAX_PACE = 1000.0
"""The fastest pace held; beyond it a run is not paced in practice (0 says so)."""


@dataclass(frozen=True)
class LiveOptions:
    """Where to serve and how fast to run.

    ``port`` 0 asks the operating system for a free port (the stream reports the one it
    got); ``pace`` is the rate of real time to hold (1.0: real time, 2.0: twice as fast,
    0: as fast as the run goes).
    """

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    pace: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.port, int) or isinstance(self.port, bool) \
                or not 0 <= self.port <= 65535:
            raise ConfigError(f"--port {self.port!r}: expected a TCP port number in "
                              "0..65535 (0: any free port)")
        if not isinstance(self.pace, (int, float)) or isinstance(self.pace, bool) \
                or not math.isfinite(self.pace) or not (self.pace == 0.0 or
                                                        MIN_PACE <= self.pace <= MAX_PACE):
            raise ConfigError(f"--pace {self.pace!r}: expected 0 (as fast as it goes) or a "
                              f"rate of real time in [{MIN_PACE:g}, {MAX_PACE:g}] (1: real "
                              "time)")
        if not self.host:
            raise ConfigError("--host '': expected an address to listen on "
                              "(127.0.0.1 unless you mean to serve other machines)")


def _subscription_listener(stream: LiveStream) -> Any:
    """The server's listener: asks ``stream`` to re-send a latched topic on subscription.

    The callback comes on the server's thread; it only notes the topic, and the run's thread
    sends it with its next message (never two threads logging on one channel at once).
    """
    from foxglove.websocket import ServerListener

    class Subscriptions(ServerListener):
        def on_subscribe(self, client: Any, channel: Any) -> None:
            del client
            stream.request_latched(channel.topic)

    return Subscriptions()


def _free_to_serve(options: LiveOptions) -> int:
    """The port to serve on, checked now so that a busy port or a bad address is refused
    before the run (for ``port`` 0: one the system has free)."""
    try:
        (family, kind, proto, _, address), *_ = socket.getaddrinfo(
            options.host, options.port, type=socket.SOCK_STREAM)
        with socket.socket(family, kind, proto) as probe:
            probe.bind(address)
            return int(probe.getsockname()[1])
    except OSError as error:
        reason = error.strerror or str(error)
        raise ConfigError(f"--port {options.port} on {options.host}: cannot serve "
                          f"({reason}); expected a free port (--port 0 picks one) on an "
                          "address of this machine") from None


class LiveStream:
    """A Foxglove WebSocket server on a run's log channels (see the module docstring).

    Use as a context manager (the server stops on exit); give it to the recorder
    (``McapRecorder(..., live=stream)``), which calls the :class:`cosim.log.recorder.LiveSink`
    methods.
    """

    def __init__(self, options: LiveOptions) -> None:
        self.options = options
        self._context: Any = None
        self._resent: dict[str, Any] = {}
        """The stream's own channel of each latched topic (what late clients get)."""
        self._latched: dict[str, tuple[bytes, int]] = {}
        self._resend: set[str] = set()
        self._lock = threading.Lock()
        self._epoch_ns: int | None = None
        self._wall_start_s = 0.0
        self._next_time_ns = 0
        self._port = _free_to_serve(options)
        self._server: Any = None
        self._closed = False

    def _start(self) -> None:
        """Start the server: at the run's first message, when the channels of the log's
        header exist, so a client that connects gets them in one advertisement. (A client
        that connected while channels were being created one by one could subscribe to
        one in the instant the server had announced it but not yet filed it.)"""
        import foxglove
        from foxglove.websocket import Capability

        try:
            self._server = foxglove.start_server(
                name="cosim", host=self.options.host, port=self._port, context=self._context,
                capabilities=[Capability.Time], message_backlog_size=MESSAGE_BACKLOG,
                server_listener=_subscription_listener(self), channel_filter=_served)
        except (RuntimeError, OverflowError, ValueError) as error:
            reason = str(error).removeprefix("FoxgloveError: ")
            raise ConfigError(f"--port {self._port} on {self.options.host}: cannot serve "
                              f"({reason}); expected a free port (--port 0 picks one)") from None

    @property
    def port(self) -> int:
        """The port the server listens on (the one the system chose for ``port`` 0)."""
        return self._port

    @property
    def url(self) -> str:
        """The WebSocket address to open in Foxglove (``Open connection`` > Foxglove WebSocket)."""
        host = self.options.host
        shown = f"[{host}]" if ":" in host else host
        return f"ws://{shown}:{self.port}"

    def __enter__(self) -> LiveStream:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the server (idempotent); connected clients see the connection close.

        ``stop()`` waits for every client to take what is queued for it, so a client that
        has stopped reading held the command for most of a minute after the run. It is
        waited for :data:`STOP_WAIT_S` at most; then a warning says so and the connection is
        left to close with the process."""
        self._closed = True
        server, self._server = self._server, None
        if server is None:
            return
        stopping = threading.Thread(target=server.stop, name="cosim-live-stop", daemon=True)
        stopping.start()
        stopping.join(STOP_WAIT_S)
        if stopping.is_alive():
            warnings.warn(f"live: a client of {self.url} is not reading what it was sent: "
                          "its connection is left to close when this command ends",
                          LiveClientStalled, stacklevel=2)

    # The recorder's LiveSink protocol.
    def attach(self, context: Any) -> None:
        """Serve the channels of ``context`` (the recorder's), from its first message."""
        self._context = context

    def registered(self, topic: str, schema: Any) -> None:
        """A log channel; a latched topic gets a channel of the stream's own besides, on
        which it is sent to clients (and sent again to each client that subscribes)."""
        if topic not in LATCHED_TOPICS:
            return
        from foxglove import Channel

        with _one_channel_per_topic_said(topic):
            self._resent[topic] = Channel(topic, schema=schema, message_encoding="json",
                                          context=self._context,
                                          metadata={LIVE_ONLY: "latched"})

    def due(self, log_time_ns: int) -> None:
        """Pace to the message's simulated time; start the server at the first message."""
        if self._server is None and not self._closed:
            self._start()
        if self._epoch_ns is None:
            self._epoch_ns = log_time_ns
            self._wall_start_s = time.perf_counter()
        if self.options.pace > 0:
            due_s = self._wall_start_s + (log_time_ns - self._epoch_ns) * 1e-9 / self.options.pace
            wait_s = due_s - time.perf_counter()
            if wait_s > 0:
                time.sleep(wait_s)
        if self._resend:
            self._send_latched()

    def sent(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """After a message reached the sinks: a latched one goes to the clients on the
        stream's own channel; the simulated time is broadcast every 50 ms of it."""
        resent = self._resent.get(topic)
        if resent is not None:
            self._latched[topic] = (data, log_time_ns)
            resent.log(data, log_time=log_time_ns)
        if log_time_ns >= self._next_time_ns and self._server is not None:
            self._server.broadcast_time(log_time_ns)
            self._next_time_ns = log_time_ns + TIME_BROADCAST_PERIOD_NS

    def request_latched(self, topic: str) -> None:
        """Note that a client has just subscribed to ``topic`` (the server's thread)."""
        if topic in LATCHED_TOPICS:
            with self._lock:
                self._resend.add(topic)

    def _send_latched(self) -> None:
        with self._lock:
            topics, self._resend = self._resend, set()
        for topic in topics:
            latched = self._latched.get(topic)
            if latched is not None:
                self._resent[topic].log(latched[0], log_time=latched[1])


def _served(channel: Any) -> bool:
    """The server's channel filter: a latched topic on the stream's own channel only (the
    log's channel of it is the file's), every other topic on the log's channel."""
    return channel.topic not in LATCHED_TOPICS or LIVE_ONLY in channel.metadata


class _SameTopicNotice(logging.Filter):
    def __init__(self, topic: str) -> None:
        super().__init__()
        self.topic = topic

    def filter(self, record: logging.LogRecord) -> bool:
        return f"topic {self.topic} already exists" not in record.getMessage()


@contextlib.contextmanager
def _one_channel_per_topic_said(topic: str) -> Iterator[None]:
    """foxglove-sdk logs a warning (logger ``foxglove.context``) when a second channel of a
    topic is created on a context: meant for a user's mistake, here the design (the file's
    channel and the stream's own never reach the same sink). That one notice is left out
    while the stream's channel is created; the logger is as it was afterwards."""
    logger = logging.getLogger("foxglove.context")
    notice = _SameTopicNotice(topic)
    logger.addFilter(notice)
    try:
        yield
    finally:
        logger.removeFilter(notice)
