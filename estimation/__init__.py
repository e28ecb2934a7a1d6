"""State estimation: Kalman filters (filterpy) with their process and measurement models."""
