"""What the packages' rostest check nodes share: waiting on a condition in wall time.

The simulator runs as fast as it can (real_time_factor 0) or slower under load, so a check waits
in wall time, never in sim time, and never without a bound.
"""
import time

import rospy


def wait_until(predicate, timeout_s: float, period_s: float = 0.05) -> bool:
    """True as soon as ``predicate()`` holds; after ``timeout_s`` of wall time [s] (or at shutdown) its last value."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end and not rospy.is_shutdown():
        if predicate():
            return True
        time.sleep(period_s)
    return predicate()
