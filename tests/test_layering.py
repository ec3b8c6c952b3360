"""House rule: pure cores carry no ROS imports.

Everything under src/<pkg>/src/<pkg>/ except the ros/ sub-package must be
importable without a ROS master and without rospy, tf2_ros, actionlib,
cv_bridge or any *_msgs package, so it can be unit-tested and reused.
"""
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
ROS_IMPORT = re.compile(
    r"^\s*(?:import|from)\s+(rospy|rosbag|rostest|roslaunch|tf2_ros|tf|actionlib|cv_bridge|"
    r"message_filters|[A-Za-z0-9_]+_msgs)\b",
    re.MULTILINE,
)


def core_files():
    for pkg_src in sorted(ROOT.glob("src/*/src/*")):
        for path in sorted(pkg_src.rglob("*.py")):
            if "ros" not in path.relative_to(pkg_src).parts:
                yield path


@pytest.mark.parametrize("path", list(core_files()), ids=lambda p: str(p.relative_to(ROOT)))
def test_core_module_has_no_ros_import(path):
    text = path.read_text()
    found = ROS_IMPORT.findall(text)
    assert not found, f"{path.relative_to(ROOT)} imports {found}; move the ROS part into a ros/ sub-package"


def test_the_rule_catches_a_ros_import():
    assert ROS_IMPORT.search("import rospy\n")
    assert ROS_IMPORT.search("from sensor_msgs.msg import Image\n")
    assert not ROS_IMPORT.search("import numpy as np\n")
