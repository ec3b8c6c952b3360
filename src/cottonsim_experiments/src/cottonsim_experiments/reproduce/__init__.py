"""Experiment plans, runs and summaries that reproduce the paper (no ROS imports).

* :mod:`.row_spacing`: the paper's Fig. 3a row-spacing study (plan, per-attempt
  settings, classification of each attempt, the smallest traversable spacing);
* :mod:`.seeds`: mean and spread of report figures over several seeds;
* :mod:`.launcher`: runs one roslaunch bringup in a subprocess on its own
  master port, shows its progress and stops it cleanly;
* :mod:`.results_doc`: renders docs/results.md from the results folders.

The command-line front end is ``rosrun cottonsim_navigation reproduce``.
"""
