"""map_server: serve an occupancy map from a map_server YAML + image, or an empty map.

The ROS map_server is not packaged for Debian; this node does its job. The
file is read by ``cottonsim_common.map_files.load_map_yaml`` (PGM or any
OpenCV image, trinary / scale modes); the empty map comes from
``cottonsim_common.map_files.empty_map``.
"""
from __future__ import annotations

import rospy
from nav_msgs.msg import MapMetaData, OccupancyGrid
from nav_msgs.srv import GetMap, GetMapResponse

from cottonsim_common.map_files import EmptyMapConfig, empty_map, load_map_yaml
from cottonsim_common.ros.conversions import occupancy_grid_msg
from cottonsim_common.ros.params import config_from_params, typed_param


class MapServerNode:
    """Publishes one map, latched, and answers static_map.

    Publications
      map            nav_msgs/OccupancyGrid  latched, frame ~frame_id
      map_metadata   nav_msgs/MapMetaData    latched
    Services
      static_map     nav_msgs/GetMap         the same map
    Parameters (private)
      ~map_file (str, ""): map_server YAML; the first command-line argument
          is used when the parameter is empty (``rosrun ... map_server map.yaml``)
      ~frame_id (str, "map"): frame of the published map
      ~empty_map (bool, false): serve a free map instead of a file (GPS mode)
      ~width_m, ~height_m (float, 100, 100): extent of the empty map [m]
      ~resolution (float, 0.05): cell size of the empty map [m]
      ~origin ([x m, y m, yaw rad], [-50, -50, 0]): lower-left corner of the empty map
    TF: none. A missing or malformed file makes the node log fatal and exit 2.
    """

    def __init__(self, argv=()):
        self.frame_id = typed_param("~frame_id", "map")
        if not self.frame_id:
            raise ValueError("parameter ~frame_id: must not be empty")
        if typed_param("~empty_map", False):
            config = config_from_params(EmptyMapConfig)
            grid, resolution, origin = empty_map(config)
            source = f"empty map {config.width_m} x {config.height_m} m"
        else:
            map_file = typed_param("~map_file", "")
            if not map_file:
                args = [a for a in argv[1:] if not a.startswith("__")]
                map_file = args[0] if args else ""
            if not map_file:
                raise ValueError("no map given: set ~map_file or pass the YAML path as argument "
                                 "(or ~empty_map:=true)")
            grid, resolution, origin = load_map_yaml(map_file)
            source = map_file
        self.map_msg = occupancy_grid_msg(grid, resolution, origin, self.frame_id, rospy.Time.now())
        self.map_pub = rospy.Publisher("map", OccupancyGrid, queue_size=1, latch=True)
        self.meta_pub = rospy.Publisher("map_metadata", MapMetaData, queue_size=1, latch=True)
        self.meta_pub.publish(self.map_msg.info)
        self.map_pub.publish(self.map_msg)
        self.service = rospy.Service("static_map", GetMap, self._on_static_map)
        rospy.loginfo("map_server: %s, %d x %d cells at %.3f m, origin (%.2f, %.2f, %.2f), frame %s", source,
                      grid.shape[1], grid.shape[0], resolution, origin[0], origin[1], origin[2], self.frame_id)

    def _on_static_map(self, _request):
        return GetMapResponse(map=self.map_msg)
