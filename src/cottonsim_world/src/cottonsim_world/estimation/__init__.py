"""State estimation on the robot side (odometry EKF), fed by the simulated sensors."""
