"""The ROS helpers every package's thin ROS layer shares; the only part of cottonsim_common that imports rospy."""
