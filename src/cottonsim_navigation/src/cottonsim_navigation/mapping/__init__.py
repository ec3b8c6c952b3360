"""Mapping cores: gmapping-style scan matcher and Rao-Blackwellised particle-filter SLAM."""
