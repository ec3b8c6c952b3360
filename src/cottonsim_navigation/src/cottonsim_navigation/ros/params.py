"""Moved to :mod:`cottonsim_common.ros.params`; this name stays for the callers not yet switched
(ros/amcl_node.py and benchmarks/kidnap_relocalization_sim.py)."""
from cottonsim_common.ros.params import config_from_params, typed_param  # noqa: F401
