"""mapping_supervisor: end a mapping run by saving the SLAM map once the exploration route is done.

mapping.launch drives the farm's route (with cottonsim_world's route_driver, or
the map waypoint navigator on the map that slam_gmapping is building); when the
driver reports done (route_driver: ~done true; navigator: state "finished") this
node fetches the map from the SLAM node's dynamic_map service, crops it to the
observed area plus a margin (cottonsim_navigation.mapping.map_crop), writes it
like map_saver (cottonsim_common.map_files.save_map) and shuts down
(as a required node this ends the launch).
"""
from __future__ import annotations

import json
import os

import numpy as np
import rospy
from nav_msgs.srv import GetMap
from std_msgs.msg import Bool, String

from cottonsim_common.map_files import MapSaverConfig, save_map
from cottonsim_common.ros.conversions import occupancy_grid_to_array
from cottonsim_common.ros.params import typed_param
from cottonsim_navigation.mapping.map_crop import crop_to_known


class MappingSupervisorNode:
    """Saves the SLAM map when the exploration route is finished.

    Subscriptions
      ~state_topic (default /map_waypoint_navigator/state)  std_msgs/String  the navigator's JSON state;
          {"state": "finished", ...} triggers the save (unparsable messages are warned about and ignored)
      ~done_topic (default /route_driver/done)  std_msgs/Bool  the route driver's end flag; true triggers the
          save, false (route not finished, e.g. its time-out) too, with a warning
    Publications
      ~saved  std_msgs/String (latched)  the written map YAML path once the map is saved (tests, scripts)
    Service clients
      ~map_service (default /dynamic_map)  nav_msgs/GetMap  the SLAM node's current map
    Parameters (private)
      ~map_file (str, required): output base name, writes <map_file>.pgm and <map_file>.yaml (folder made)
      ~crop_margin_m (float, 1.0): margin kept around the observed cells [m]
      ~settle_s (float, 2.0): sim time waited after "finished" before the map is fetched (last scans) [s]
      ~occupied_thresh (float, 65), ~free_thresh (float, 19.6): map_saver's thresholds on OccupancyGrid values
      ~shutdown_when_done (bool, true): end the node after saving (false: keep running until shut down)
    """

    def __init__(self):
        self.map_file = typed_param("~map_file", "")
        if not self.map_file:
            raise ValueError("parameter ~map_file must be set (output base name)")
        self.state_topic = typed_param("~state_topic", "/map_waypoint_navigator/state")
        self.map_service = typed_param("~map_service", "/dynamic_map")
        self.margin_m = typed_param("~crop_margin_m", 1.0, minimum=0.0)
        self.settle_s = typed_param("~settle_s", 2.0, minimum=0.0)
        self.shutdown_when_done = typed_param("~shutdown_when_done", True)
        self.saver_config = MapSaverConfig(occupied_thresh=typed_param("~occupied_thresh", 65.0),
                                           free_thresh=typed_param("~free_thresh", 19.6))
        self.finished = False
        self.saved_pub = rospy.Publisher("~saved", String, queue_size=1, latch=True)
        self.done_topic = typed_param("~done_topic", "/route_driver/done")
        rospy.Subscriber(self.state_topic, String, self._on_state, queue_size=5)
        if self.done_topic:
            rospy.Subscriber(self.done_topic, Bool, self._on_done, queue_size=1)
        rospy.loginfo("mapping_supervisor: will save the map to %s when %s says finished", self.map_file,
                      self.state_topic)

    def _on_state(self, msg: String) -> None:
        try:
            state = json.loads(msg.data).get("state")
        except (ValueError, AttributeError):
            rospy.logwarn_throttle(10.0, f"mapping_supervisor: state is not a JSON object: {msg.data[:80]!r}")
            return
        if state == "finished":
            self.finished = True

    def _on_done(self, msg: Bool) -> None:
        if not msg.data:
            rospy.logwarn("mapping_supervisor: the route driver stopped before the end of its route; saving anyway")
        self.finished = True

    def save(self) -> bool:
        """Fetch, crop and write the map; True on success."""
        rospy.wait_for_service(self.map_service, 30.0)
        msg = rospy.ServiceProxy(self.map_service, GetMap)().map
        grid, res, origin = occupancy_grid_to_array(msg)
        cropped, corigin = crop_to_known(grid, res, origin, self.margin_m)
        os.makedirs(os.path.dirname(os.path.abspath(self.map_file)), exist_ok=True)
        pgm, yaml_path = save_map(self.map_file, cropped, res, corigin, self.saver_config)
        rospy.loginfo("mapping_supervisor: %d x %d map (cropped from %d x %d) saved to %s, %s; %d occupied cells",
                      cropped.shape[1], cropped.shape[0], grid.shape[1], grid.shape[0], pgm, yaml_path,
                      int(np.count_nonzero(cropped >= 65)))
        self.saved_pub.publish(String(data=os.path.abspath(yaml_path)))
        return True

    def spin(self) -> int:
        rate = rospy.Rate(5.0)
        while not rospy.is_shutdown() and not self.finished:
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                return 1
        if rospy.is_shutdown():
            return 1
        if self.settle_s > 0:
            rospy.sleep(self.settle_s)
        try:
            ok = self.save()
        except (rospy.ROSException, rospy.ServiceException, ValueError, OSError) as exc:
            rospy.logerr(f"mapping_supervisor: cannot save the map: {exc}")
            ok = False
        if self.shutdown_when_done:
            rospy.signal_shutdown("map saved" if ok else "map not saved")
        else:
            rospy.spin()      # stay up (a required node): the launch goes on and ~saved stays latched
        return 0 if ok else 1
