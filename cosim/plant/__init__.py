"""The truth: the MuJoCo car, its tyres and actuation, traffic and disturbances."""
