"""Adaptive cruise control: the ACC law, its settings and extremum seeking."""
