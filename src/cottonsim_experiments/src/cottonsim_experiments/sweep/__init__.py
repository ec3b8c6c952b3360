"""Experiment sweeps on Ray: a grid of runs from a YAML file, each run one bringup (see docs/sweeps.md)."""
