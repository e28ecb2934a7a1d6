"""cosim: a MuJoCo co-simulation testbed for autonomous-car path tracking."""

from __future__ import annotations

__version__ = "0.1.0"
