"""A pure-pursuit tracker for cosim, installed as a plug-in (entry point ``my-pursuit``)."""

from cosim_pursuit.tracker import PurePursuit

__all__ = ["PurePursuit"]
