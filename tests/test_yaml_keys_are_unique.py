"""House rule: no shipped YAML file gives a key twice in one mapping.

roslaunch's rosparam loader cannot be made strict, so every YAML and RViz file
of the repository is read here with cottonsim_common's strict loader.
"""
from repository_files import ROOT, repository_files

from cottonsim_common.config.yaml_files import load_yaml_file


def test_every_yaml_file_of_the_repository_has_unique_keys():
    names = repository_files("*.yaml", "*.yml", "*.rviz")
    assert len(names) > 20
    for name in names:
        load_yaml_file(ROOT / name)
