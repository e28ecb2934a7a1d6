"""Classic path trackers to measure the MPCs against: PID, Stanley, pure pursuit, LQR."""
