"""One navigation run's record and report against the simulator's ground truth (no ROS imports)."""
