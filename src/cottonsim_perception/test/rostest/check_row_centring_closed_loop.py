#!/usr/bin/env python3
"""rostest node: drive a lane steered only by /husky/cv/coords; end on the centre line, touch no plant.

The test node is the whole 'navigator': each [linear_x, angular_z] from the
row-centring node goes to /cmd_vel, repeated at 20 Hz (sim time) while the
last estimate is younger than 0.5 s (the bridge stops the robot 0.25 s
after the last command, so a silent row-centring node stops the robot).
"""
import threading
import unittest

import rospy
import rostest
from cottonsim_msgs.msg import PlantContacts
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64MultiArray

from cottonsim_common.ros.testing import wait_until


class RowCentringClosedLoopTest(unittest.TestCase):
    def setUp(self):
        self.lane_x = float(rospy.get_param("/lane_centre_x_m"))
        self.distance = float(rospy.get_param("/drive_distance_m"))
        self.tolerance = float(rospy.get_param("/tolerance_m"))
        self.lock = threading.Lock()
        self.truth = None
        self.contacts = None
        self.coords = None            # (stamp, linear_x, angular_z)
        self.estimates = 0
        rospy.Subscriber("/ground_truth/odom", Odometry, lambda m: setattr(self, "truth", m))
        rospy.Subscriber("/ground_truth/plant_contacts", PlantContacts, lambda m: setattr(self, "contacts", m))
        rospy.Subscriber("/husky/cv/coords", Float64MultiArray, self.on_coords, queue_size=1)
        self.cmd = rospy.Publisher("/cmd_vel", Twist, queue_size=1)

    def on_coords(self, msg):
        if len(msg.data) != 2:
            return
        with self.lock:
            self.coords = (rospy.Time.now(), msg.data[0], msg.data[1])
            self.estimates += 1
        self.send()

    def send(self):
        with self.lock:
            c = self.coords
        cmd = Twist()
        if c is not None and (rospy.Time.now() - c[0]).to_sec() < 0.5:
            cmd.linear.x, cmd.angular.z = c[1], c[2]
        self.cmd.publish(cmd)

    def test_drive_lane_centred(self):
        self.assertTrue(wait_until(lambda: self.truth is not None, 60.0), "no /ground_truth/odom within 60 s (wall)")
        p0 = self.truth.pose.pose.position
        x0, y0 = p0.x, p0.y
        self.assertAlmostEqual(x0 - self.lane_x, 0.15, delta=0.02, msg="spawned elsewhere than the test asks")
        timer = rospy.Timer(rospy.Duration(0.05), lambda _: self.send())
        start = rospy.Time.now()
        while not rospy.is_shutdown():
            p = self.truth.pose.pose.position
            if p.y - y0 >= self.distance:
                break
            self.assertLess((rospy.Time.now() - start).to_sec(), 60.0,
                            f"only {p.y - y0:.2f} m driven in 60 s of sim time ({self.estimates} estimates)")
            rospy.rostime.wallsleep(0.02)
        timer.shutdown()
        self.cmd.publish(Twist())
        p = self.truth.pose.pose.position
        lateral = p.x - self.lane_x
        rospy.loginfo("closed loop: drove %.2f m, start offset %+.3f m, end offset %+.3f m, %d estimates",
                      p.y - y0, x0 - self.lane_x, lateral, self.estimates)
        print(f"closed loop: end offset {lateral:+.3f} m after {p.y - y0:.2f} m, {self.estimates} estimates")
        self.assertGreater(self.estimates, 50, "row centring gave too few estimates")
        self.assertLess(abs(lateral), self.tolerance, f"ended {lateral:+.3f} m off the lane centre line")
        rospy.sleep(0.3)
        self.assertIsNotNone(self.contacts, "no /ground_truth/plant_contacts received")
        self.assertEqual(self.contacts.total_contact_events, 0,
                         f"touched plants {list(self.contacts.plants_touched)}")


if __name__ == "__main__":
    rospy.init_node("check_row_centring_closed_loop")
    rostest.rosrun("cottonsim_perception", "row_centring_closed_loop", RowCentringClosedLoopTest)
