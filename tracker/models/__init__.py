"""The controllers' vehicle models: bicycle models as CasADi expressions, tyre limits."""
