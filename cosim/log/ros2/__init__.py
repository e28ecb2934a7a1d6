"""A run's log as standard ROS 2 messages: ``cosim export --ros2 LOG.mcap``.

- :mod:`cosim.log.ros2.types`: the message types (rosbags' typestore of ROS 2 Humble and
  later, plus ``ackermann_msgs``, registered from its definition);
- :mod:`cosim.log.ros2.messages`: one function per ROS message, from cosim's logged
  messages (the mapping, frames, covariances and units);
- :mod:`cosim.log.ros2.bag`: the export: read the log, write an MCAP with the ``ros2``
  profile, ``ros2msg`` schemas and CDR messages.

rosbags is an optional dependency (``pip install 'cosim[ros2]'``): only these modules import
it, and only for an export (:func:`require_rosbags` says how to install it).
"""

from __future__ import annotations

import importlib.util

from cosim.core.exceptions import CosimError


def require_rosbags() -> None:
    """Refuse an export in one line when rosbags is not installed."""
    if importlib.util.find_spec("rosbags") is None:
        raise CosimError("--ros2: the ROS 2 export needs rosbags: pip install 'cosim[ros2]' "
                         "(or pip install rosbags)")
