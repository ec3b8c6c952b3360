"""ROS adapters of the experiments: the experiment recorder node."""
