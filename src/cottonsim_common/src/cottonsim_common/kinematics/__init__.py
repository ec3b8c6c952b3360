"""Robot kinematics shared by the simulator and the robot-side arm code (no ROS, numpy only)."""
