"""Model-predictive path trackers: the NMPC family, the delta-u MPC, the LTV-MPC and what
they share."""
