"""Physical constants every layer's models share (SI)."""

GRAVITY_MPS2 = 9.81
"""Gravitational acceleration [m/s^2]."""

AIR_DENSITY_KGPM3 = 1.225
"""ISA sea-level air density [kg/m^3]."""
