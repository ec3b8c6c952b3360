"""Shared by the rostest check nodes: poll a condition in wall time (the sim clock may run at any rate)."""
import time

import rospy


def wait_until(predicate, timeout_s: float, period_s: float = 0.05) -> bool:
    """True as soon as ``predicate()`` holds; after ``timeout_s`` of wall time [s] its last value."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end and not rospy.is_shutdown():
        if predicate():
            return True
        time.sleep(period_s)
    return predicate()
