"""How long ``cosim export --ros2`` takes on a full lane-change log (measures, prints).

    .venv/bin/python bench/ros2_export.py [--log LOG.mcap] [--repeats 5]

Without ``--log`` it first runs the 15 s lane change (seed 0, default tracker) to a temporary
log. Then it times, median and maximum over the repeats, (a) :func:`export_ros2` in this
process (reading the JSON log, building and serialising every ROS 2 message, writing the
MCAP) and (b) the whole command ``cosim export --ros2`` in a fresh process (Python start and
imports included), and prints the message count and the cost per message.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cosim.log.ros2.bag import export_ros2
from cosim.simulation.runner import run
from cosim.simulation.scenario_config import load_config

COSIM = str(Path(sys.executable).with_name("cosim"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--log", type=Path, help="a run log (default: run the lane change)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="cosim-bench-ros2-") as work:
        log = args.log
        if log is None:
            log = Path(work) / "lane-change.mcap"
            run(load_config("lane-change"), log)
        in_process, command = [], []
        messages = 0
        for i in range(args.repeats):
            out = Path(work) / f"bag-{i}.mcap"
            start = time.perf_counter()
            result = export_ros2(log, out)
            in_process.append(time.perf_counter() - start)
            messages = sum(result.message_counts.values())
            start = time.perf_counter()
            subprocess.run([COSIM, "export", "--ros2", str(log), "--out",
                            str(Path(work) / f"cli-{i}.mcap")], check=True,
                           capture_output=True)
            command.append(time.perf_counter() - start)
        size_mb = out.stat().st_size / 1e6
    print(f"{log.name}: {messages} ROS 2 messages, {size_mb:.2f} MB; "
          f"median / max of {args.repeats}")
    for name, times in (("export_ros2 (in process)", in_process),
                        ("cosim export --ros2 (new process)", command)):
        median = statistics.median(times)
        print(f"  {name:<34} {median:6.3f} s / {max(times):6.3f} s  "
              f"({median / messages * 1e6:5.1f} us per message)")


if __name__ == "__main__":
    main()
