"""Waiting for a running sweep or comparison to land its first rows."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path


def wait_for_rows(process: subprocess.Popen, rows_file: Path, count: int = 1,
                  timeout_s: float = 600.0) -> None:
    """Return once ``rows_file`` (JSON lines) holds ``count`` rows; fail if ``process``
    ends first or nothing lands within ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not (rows_file.is_file() and rows_file.read_text().count("\n") >= count):
        assert process.poll() is None, "the process ended before its rows were seen"
        assert time.monotonic() < deadline, "no row landed in time"
        time.sleep(0.05)
