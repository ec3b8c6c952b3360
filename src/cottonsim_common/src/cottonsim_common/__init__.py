"""Shared by the simulator (cottonsim_world) and the robot-side stack (navigation, perception)."""
