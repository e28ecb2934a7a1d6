"""Path tracking: reference paths, bicycle models and model-predictive controllers."""
