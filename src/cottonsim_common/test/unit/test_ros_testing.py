"""cottonsim_common.ros.testing: the rostest checks' bounded wait (no ROS master needed)."""
from cottonsim_common.ros.testing import wait_until


def test_wait_until_returns_once_the_condition_holds_and_false_after_the_timeout():
    calls = []

    def third_call():
        calls.append(1)
        return len(calls) >= 3

    assert wait_until(third_call, timeout_s=60.0, period_s=0.001)
    assert len(calls) == 3                       # polled until it held, not once more
    assert wait_until(lambda: False, timeout_s=0.01, period_s=0.001) is False
