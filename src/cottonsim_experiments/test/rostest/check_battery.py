#!/usr/bin/env python3
"""rostest node: /battery/state rate, drain at rest and while driving, sanity of every field."""
import unittest

import rospy
import rostest
from geometry_msgs.msg import Twist
from sensor_msgs.msg import BatteryState

from cottonsim_common.ros.testing import wait_until

IDLE_W, MOTION_W_PER_MPS, SCALE = 60.0, 120.0, 50.0       # config/battery.yaml + the test's drain_scale
V_FULL, V_EMPTY, CAPACITY_AH = 25.46, 23.16, 20.0


class BatteryTest(unittest.TestCase):
    def setUp(self):
        self.states = []
        rospy.Subscriber("/battery/state", BatteryState, self.states.append)
        self.cmd = rospy.Publisher("/cmd_vel", Twist, queue_size=1)

    def check_sane(self, s):
        self.assertTrue(0.0 <= s.percentage <= 1.0, s.percentage)
        # the real pack's numbers, whatever the fast-forward: 23-25.5 V, 60..~200 W of draw
        self.assertTrue(V_EMPTY - 0.5 < s.voltage <= V_FULL, s.voltage)
        self.assertTrue(IDLE_W / V_FULL <= -s.current < 200.0 / V_EMPTY, s.current)
        self.assertAlmostEqual(s.charge, s.percentage * CAPACITY_AH, delta=1e-3)
        self.assertAlmostEqual(s.design_capacity, CAPACITY_AH, delta=1e-6)
        self.assertTrue(s.present)
        self.assertEqual(s.power_supply_status, BatteryState.POWER_SUPPLY_STATUS_DISCHARGING)

    def command(self, v, duration_s):
        """Command forward speed v [m/s] for duration_s of sim time."""
        end = rospy.Time.now() + rospy.Duration(duration_s)
        msg = Twist()
        msg.linear.x = v
        while rospy.Time.now() < end and not rospy.is_shutdown():
            self.cmd.publish(msg)
            rospy.sleep(0.02)

    def drain_per_s(self, v, duration_s):
        """Percentage drop per second of sim time over duration_s while commanding v [m/s]."""
        first = len(self.states)
        self.command(v, duration_s)
        window = self.states[first + 1:]                  # skip the state that straddles the start
        self.assertGreaterEqual(len(window), 3)
        a, b = window[0], window[-1]
        dt = (b.header.stamp - a.header.stamp).to_sec()
        return (a.percentage - b.percentage) / dt, window

    def test_drain(self):
        self.assertTrue(wait_until(lambda: len(self.states) >= 2, 60.0), "fewer than 2 battery states in 60 s (wall)")
        first = self.states[0]
        self.assertAlmostEqual(first.percentage, 0.41, delta=0.01)
        rest, w1 = self.drain_per_s(0.0, 6.0)
        # ~rate 1 Hz in sim time (the mean interval; the first one after start-up may be short)
        period = (w1[-1].header.stamp - w1[0].header.stamp).to_sec() / (len(w1) - 1)
        self.assertAlmostEqual(period, 1.0, delta=0.05)
        # idle: P = 60 W x 50; I = P / V_oc(41 %); percentage per s = I / 3600 / 20 Ah
        v_oc = V_EMPTY + (V_FULL - V_EMPTY) * w1[0].percentage
        expected_rest = IDLE_W * SCALE / v_oc / 3600.0 / CAPACITY_AH
        self.assertAlmostEqual(rest, expected_rest, delta=0.05 * expected_rest)
        # driving at 0.5 m/s: 60 + 120 x 0.5 = 120 W, twice the idle draw (minus start-up)
        self.command(0.5, 2.0)                                # reach the cruise speed first
        driving, w2 = self.drain_per_s(0.5, 6.0)
        self.cmd.publish(Twist())
        ratio = driving / rest
        rospy.loginfo("check_battery: %.5f %%/s at rest, %.5f %%/s driving (ratio %.2f)", rest * 100,
                      driving * 100, ratio)
        self.assertAlmostEqual(ratio, (IDLE_W + MOTION_W_PER_MPS * 0.5) / IDLE_W, delta=0.25)
        states = w1 + w2
        for s in states:
            self.check_sane(s)
        pct = [s.percentage for s in states]
        self.assertTrue(all(b < a for a, b in zip(pct, pct[1:])), "percentage did not fall steadily")
        self.assertLess(states[-1].voltage, first.voltage)


if __name__ == "__main__":
    rospy.init_node("check_battery")
    rostest.rosrun("cottonsim_experiments", "battery_check", BatteryTest)
