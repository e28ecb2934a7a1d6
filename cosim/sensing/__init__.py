"""Noisy views of the truth: the sensors and the faults applied to them."""
