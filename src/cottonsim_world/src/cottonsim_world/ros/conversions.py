"""Moved to :mod:`cottonsim_common.ros.conversions`; this name stays for the callers not yet switched
(cottonsim_navigation/ros/amcl_node.py and cottonsim_perception/ros/*_node.py)."""
from cottonsim_common.ros.conversions import *  # noqa: F401,F403
