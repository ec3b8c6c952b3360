"""map_saver: write the next map received on a topic as <name>.pgm + <name>.yaml, then exit.

Like ROS map_saver (not packaged for Debian): trinary thresholds on the
OccupancyGrid values, the YAML map_server reads back. The conversion and the
file writing are ``cottonsim_common.map_files.save_map``.
"""
from __future__ import annotations

import threading
import time

import rospy
from nav_msgs.msg import OccupancyGrid

from cottonsim_common.map_files import MapSaverConfig, save_map
from cottonsim_common.ros.conversions import occupancy_grid_to_array  # also imported from here by amcl_node
from cottonsim_common.ros.params import config_from_params, typed_param


class MapSaverNode:
    """Saves one map and stops.

    Subscriptions
      ~map_topic (default /map)   nav_msgs/OccupancyGrid   the first message is saved
    Parameters (private)
      ~file (str, "map"): output base name; writes <file>.pgm and <file>.yaml
          (a ``-f NAME`` command-line argument, as ROS map_saver takes, sets it too)
      ~map_topic (str, "/map"): topic to save
      ~occupied_thresh (float, 65): OccupancyGrid values >= this are written occupied (black)
      ~free_thresh (float, 19.6): values 0..this are written free (white); the rest grey 205
      ~timeout_s (float, 0): give up after this much wall time without a map; 0 = wait forever
    Exit status: 0 saved, 1 no map before the time-out or the map could not be written,
    2 bad parameters.
    """

    def __init__(self, argv=()):
        self.config = config_from_params(MapSaverConfig)
        self.base_path = typed_param("~file", "map")
        args = [a for a in argv[1:] if not a.startswith("__")]
        if "-f" in args:
            i = args.index("-f")
            if i + 1 >= len(args):
                raise ValueError("-f needs a file name")
            self.base_path = args[i + 1]
        if not self.base_path:
            raise ValueError("parameter ~file: must not be empty")
        self.topic = typed_param("~map_topic", "/map")
        self.timeout_s = typed_param("~timeout_s", 0.0, minimum=0.0)
        self.done = threading.Event()
        self.ok = False
        self.sub = rospy.Subscriber(self.topic, OccupancyGrid, self._on_map, queue_size=1)
        rospy.loginfo("map_saver: waiting for the map on %s", self.topic)

    def _on_map(self, msg: OccupancyGrid):
        if self.done.is_set():
            return
        try:
            grid, resolution, origin = occupancy_grid_to_array(msg)
            pgm, yaml_path = save_map(self.base_path, grid, resolution, origin, self.config)
            rospy.loginfo("map_saver: %d x %d map at %.3f m/cell saved to %s and %s", grid.shape[1],
                          grid.shape[0], resolution, pgm, yaml_path)
            self.ok = True
        except (ValueError, OSError) as exc:
            rospy.logerr(f"map_saver: cannot save the map: {exc}")
        self.sub.unregister()
        self.done.set()

    def wait(self) -> int:
        """Block until the map is saved (or the time-out); returns the exit status."""
        start = time.monotonic()
        next_note = start + 5.0
        while not rospy.is_shutdown() and not self.done.wait(0.1):
            now = time.monotonic()
            if self.timeout_s > 0 and now - start > self.timeout_s:
                rospy.logerr("map_saver: no map on %s within %.1f s", self.topic, self.timeout_s)
                return 1
            if now >= next_note:
                rospy.loginfo("map_saver: still waiting for a map on %s", self.topic)
                next_note = now + 5.0
        return 0 if self.ok else 1
