#!/usr/bin/env python3
"""rostest node for the mapping bringup (mapping_bringup.test): drive, save, and the saved map's quality.

The reduced run maps the first half of lane 1 only, so the map is scored over
its observed area like slam.test (plant IoU on 0.25 m cells, precision,
rotation, shift; cottonsim_navigation.evaluation.map_quality) with the same
bounds that separate a working mapper from a broken one (a map built half a
row spacing sideways scores IoU < 0.25 and precision < 0.5). The full-farm
targets (IoU >= 0.7, rotation <= 0.5 deg) are measured by the full mapping
run (docs/map_experiment.md), not here.
"""
import os
import unittest

import rospy
import rostest
from cottonsim_msgs.msg import PlantContacts
from std_msgs.msg import Bool, String

from cottonsim_common.map_files import load_map_yaml
from cottonsim_common.ros.testing import wait_until
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.generator import generate_farm
from map_checks import assert_map_matches_truth

FARM = generate_farm(FarmConfig())       # mapping.launch's default simulator settings: the paper's farm



class MappingBringupTest(unittest.TestCase):
    def test_drive_save_and_map_quality(self):
        state = {"done": None, "saved": None, "contacts": 0}
        rospy.Subscriber("/route_driver/done", Bool, lambda m: state.__setitem__("done", m.data))
        rospy.Subscriber("/mapping_supervisor/saved", String, lambda m: state.__setitem__("saved", m.data))
        rospy.Subscriber("/ground_truth/plant_contacts", PlantContacts,
                         lambda m: state.__setitem__("contacts", m.total_contact_events))
        self.assertTrue(wait_until(lambda: state["done"] is not None, 240.0), "the route driver never finished")
        self.assertTrue(state["done"], "the route driver stopped before the end of its reduced route")
        self.assertTrue(wait_until(lambda: state["saved"] is not None, 40.0), "mapping_supervisor saved no map")
        yaml_path = state["saved"]
        self.assertEqual(yaml_path, "/tmp/cottonsim_mapping_bringup_test/map.yaml")
        self.assertTrue(os.path.isfile(yaml_path) and os.path.isfile(yaml_path[:-5] + ".pgm"))
        self.assertEqual(state["contacts"], 0, "plant contacts during the mapping drive")

        grid, res, origin = load_map_yaml(yaml_path)
        self.assertAlmostEqual(res, 0.05)
        # cropped to what ~17 m of driving observed (+1 m margin), not the 33 x 25 m extent the SLAM node holds
        self.assertLess(grid.shape[1] * res * grid.shape[0] * res, 0.6 * 33.0 * 25.0)
        assert_map_matches_truth(self, FARM, grid, res, origin, "mapping bringup")


if __name__ == "__main__":
    rospy.init_node("check_mapping_bringup")
    rostest.rosrun("cottonsim_experiments", "mapping_bringup_check", MappingBringupTest)
