"""Trackers from outside cosim: found by import path or entry point (:mod:`.loading`) and
checked field by field on every step (:mod:`.checks`)."""
