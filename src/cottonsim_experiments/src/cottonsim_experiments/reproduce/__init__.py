"""Experiment plans, runs and summaries that reproduce the paper (no ROS imports).

* :mod:`.row_spacing`: the paper's Fig. 3a row-spacing study (plan, per-attempt
  settings, classification of each attempt, the smallest traversable spacing);
* :mod:`.seeds`: mean and spread of report figures over several seeds;
* :mod:`.launcher`: runs one roslaunch bringup in a subprocess on its own
  master port, shows its progress and stops it cleanly;
* :mod:`.runs`: the route runs, the row-spacing study and the perception tables;
* :mod:`.results_doc`: renders the results page from the results folders;
* :mod:`.screenshots`: headless rviz screenshots of the bringups;
* :mod:`.packages`: where the other packages' files and commands are (rospkg, rosrun);
* :mod:`.cli`: the command line, ``rosrun cottonsim_experiments reproduce``.
"""
