"""``cosim export --ros2``: a run log as standard ROS 2 messages, for ``ros2 bag play``."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from cosim.cli.common import Handler


def add_parsers(commands: Any) -> dict[str, Handler]:
    export = commands.add_parser(
        "export", help="a log in another format: --ros2, an MCAP of ROS 2 messages")
    export.add_argument("--ros2", metavar="LOG.mcap", required=True,
                        help="the run log to export as standard ROS 2 messages (nav_msgs, "
                        "sensor_msgs, tf2_msgs, ackermann_msgs; CDR) for ros2 bag play")
    export.add_argument("--out", metavar="BAG.mcap",
                        help="the MCAP to write (default <log>-ros2.mcap beside the log)")
    export.add_argument("--force", action="store_true",
                        help="replace --out if it exists (refused otherwise)")
    return {"export": command}


def command(args: argparse.Namespace) -> int:
    from cosim.log.ros2 import require_rosbags

    require_rosbags()
    from cosim.log.ros2.bag import export_ros2

    result = export_ros2(args.ros2, args.out, args.force)
    if result.truncated:
        print(f"cosim: warning: {args.ros2!r} was cut off: exported up to its last complete "
              "record", file=sys.stderr)
    print(f"{sum(result.message_counts.values())} ROS 2 messages -> {result.path}")
    for topic, count in result.message_counts.items():
        print(f"  {topic:<20} {count}")
    print(f"replay: ros2 bag play -s mcap {result.path} --clock  (nodes with "
          "use_sim_time:=true; the stamps are simulated time from sim.epoch)")
    return 0
