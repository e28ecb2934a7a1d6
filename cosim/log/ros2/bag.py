"""``cosim export --ros2 LOG.mcap``: a run's log as an MCAP of standard ROS 2 messages.

The output is a single MCAP file as rosbag2 writes them (the MCAP specification's ``ros2``
profile: one ``ros2msg`` schema per type, named ``package/msg/Type`` and holding the type's
full definition; CDR messages serialised by rosbags; each channel's
``offered_qos_profiles``, empty, so that the player offers its default QoS; zstd chunks),
so ``ros2 bag play -s mcap BAG.mcap`` plays it and any MCAP reader opens it. What each
topic holds: :mod:`cosim.log.ros2.messages`.

Timestamps. Each message's MCAP log and publish times and its ``header.stamp`` are the
source message's log time: ``sim.epoch`` (2026-01-01T00:00:00Z unless the run set another)
plus the simulated time, in nanoseconds. So the bag lives in simulated time, months away
from the wall clock: replay it with ``ros2 bag play -s mcap BAG.mcap --clock``, which
publishes ``/clock`` from the bag's time, and start every node that should follow it (RViz,
tf2 listeners) with ``use_sim_time:=true`` (e.g. ``ros2 run rviz2 rviz2 --ros-args -p
use_sim_time:=true``); without them a node compares the 2026 stamps with its wall clock and
drops the transforms as too old or too new.

The export never touches the source log, refuses an existing ``--out`` without ``force``
and the source file itself, and writes under a temporary name that takes the final name
only when the file is complete (:class:`cosim.log.safe_file.PendingFile`): an error or an
interrupt leaves no half-written bag and whatever was at the final name untouched. A
truncated source log (a run that was killed) is exported up to its last complete record.
The run's metadata (config, seed, versions) is copied as the MCAP metadata ``cosim_run``.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from cosim import __version__
from cosim.core.config_fields import from_dict
from cosim.core.exceptions import CosimError
from cosim.core.sensor_names import GNSS, IMU
from cosim.log import topics
from cosim.log.foxglove import GeoOrigin
from cosim.log.output_claim import claim_output
from cosim.log.reader import LogSummary, iter_topics, log_file_problem, read_summary
from cosim.log.ros2 import types as ros
from cosim.log.ros2.messages import RosMessages, planar_fields_missing
from cosim.log.safe_file import PendingFile

CHUNK_SIZE_BYTES = 1 << 20
"""Uncompressed bytes per MCAP chunk."""

OUTPUTS: tuple[tuple[str, str, str, str], ...] = (
    # (source topic, ROS 2 topic, ROS 2 type, RosMessages method): each under its own
    # name, the transforms on ROS's standard /tf
    (topics.REFERENCE_PATH, topics.REFERENCE_PATH, ros.PATH, "path"),
    (topics.VEHICLE_TRUTH, topics.VEHICLE_TRUTH, ros.ODOMETRY, "truth_odometry"),
    (topics.VEHICLE_TRUTH, topics.TF, ros.TF_MESSAGE, "transforms"),
    (topics.VEHICLE_ESTIMATE, topics.VEHICLE_ESTIMATE, ros.ODOMETRY, "estimate_odometry"),
    (topics.sensor_topic(IMU), topics.sensor_topic(IMU), ros.IMU, "imu"),
    (topics.sensor_topic(GNSS), topics.sensor_topic(GNSS), ros.NAV_SAT_FIX, "nav_sat_fix"),
    (topics.CONTROL_COMMAND, topics.CONTROL_COMMAND, ros.ACKERMANN_DRIVE_STAMPED,
     "ackermann"),
)
"""Every ROS 2 topic of an export, in the order the channels are registered."""


@dataclass(frozen=True)
class ExportResult:
    """What an export wrote."""

    path: Path
    message_counts: dict[str, int]
    """Messages per ROS 2 topic."""
    truncated: bool
    """The source log was cut off; the bag holds what it had."""


def default_out(log: Path) -> Path:
    """``LOG-ros2.mcap`` beside the log."""
    return log.with_name(f"{log.stem}-ros2.mcap")


def export_ros2(log: Path | str, out: Path | str | None = None,
                force: bool = False) -> ExportResult:
    """Export the run log ``log`` to ``out`` (module docstring); bad input is a one-line
    :class:`CosimError`."""
    log = Path(log)
    summary = _run_log(log)
    out = default_out(log) if out is None else Path(out)
    # Held for the export, as a run holds its --out: a run or another export writing the
    # same file is refused, not silently replaced.
    with claim_output(out, "--out", force, [log]):
        counts = _write_bag(log, out, summary)
    return ExportResult(out, counts, summary.truncated)


def _write_bag(log: Path, out: Path, summary: LogSummary) -> dict[str, int]:
    """Every ROS 2 message of ``log`` into ``out`` (written beside it, renamed into
    place); the message count per topic."""
    origin = from_dict(GeoOrigin, summary.config.get("geo") or {}, "geo")
    store = ros.typestore()
    build = RosMessages(store, origin)
    converters: dict[str, list[tuple[str, str, Callable[[int, dict[str, Any]], Any]]]] = {}
    for source, topic, typename, method in OUTPUTS:
        converters.setdefault(source, []).append((topic, typename, getattr(build, method)))
    counts = {topic: 0 for _, topic, _, _ in OUTPUTS}
    pending = PendingFile(out)
    try:
        writer = Writer(pending.file, chunk_size=CHUNK_SIZE_BYTES,
                        compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library=f"cosim {__version__} (cosim export --ros2)")
        channels = _register(writer, store)
        writer.add_metadata("cosim_run", summary.metadata.get("run", {}))
        planar_said = False
        for source, t_ns, message in iter_topics(log, set(converters)):
            stamp_ns = summary.epoch_ns + t_ns
            if source == topics.VEHICLE_TRUTH and not planar_said:
                planar_said = True
                missing = planar_fields_missing(message)
                if missing:  # an older log: the planar state only
                    warnings.warn(f"--ros2 {str(log)!r}: /vehicle/truth has no "
                                  f"{', '.join(missing)} (a log of an older cosim): exported "
                                  "as 0", stacklevel=2)
            for topic, typename, convert in converters[source]:
                data = store.serialize_cdr(convert(stamp_ns, message), typename)
                writer.add_message(channels[topic], log_time=stamp_ns, publish_time=stamp_ns,
                                   data=bytes(data), sequence=counts[topic])
                counts[topic] += 1
        writer.finish()
        pending.publish()
    finally:
        pending.close()
    return counts


def _run_log(log: Path) -> LogSummary:
    """The summary of ``log``, refused unless it is a run log cosim wrote."""
    problem = log_file_problem(log)
    if problem is not None:
        raise CosimError(f"--ros2 {str(log)!r}: {problem} (expected the MCAP log of a cosim "
                         "run)")
    summary = read_summary(log)
    encodings = {c.topic: c.message_encoding for c in summary.channels}
    if not summary.written_by_cosim or encodings.get(topics.VEHICLE_TRUTH) != "json":
        writer = summary.library or "unknown"
        raise CosimError(f"--ros2 {str(log)!r}: not a run log (written by {writer!r}, "
                         f"topics {', '.join(sorted(encodings)[:4]) or 'none'}"
                         + (" ..." if len(encodings) > 4 else "")
                         + "): expected the MCAP log of a cosim run")
    return summary


def _register(writer: Writer, store: Any) -> dict[str, int]:
    """One ``ros2msg`` schema per type, one CDR channel per topic: topic -> channel id."""
    schemas: dict[str, int] = {}
    channels: dict[str, int] = {}
    for _, topic, typename, _ in OUTPUTS:
        if typename not in schemas:
            definition, _ = store.generate_msgdef(typename, ros_version=2)
            schemas[typename] = writer.register_schema(name=typename, encoding="ros2msg",
                                                       data=definition.encode())
        channels[topic] = writer.register_channel(topic=topic, message_encoding="cdr",
                                                  schema_id=schemas[typename],
                                                  metadata={"offered_qos_profiles": ""})
    return channels
