"""Map waypoint navigator: the paper's map-based route, one move_base goal per (x, y, yaw) waypoint.

Replaces the original's goal sender (move_base_simple/goal plus polling a
status flag that was never reset). The route file is in the map frame
(``label,x,y,yaw_rad`` CSV as the original's, "x y yaw" lines or YAML).
"""
from __future__ import annotations

from typing import List

import rospy

from cottonsim_navigation.ros.waypoint_navigator import NavigatorStartError, WaypointNavigatorBase
from cottonsim_navigation.waypoints.files import MapWaypoint, load_map_waypoints
from cottonsim_navigation.waypoints.goals import GOAL_YAW_MODES, map_goals


class MapWaypointNavigatorNode(WaypointNavigatorBase):
    """Follows a map-frame route through move_base.

    Everything of :class:`~cottonsim_navigation.ros.waypoint_navigator.WaypointNavigatorBase`
    (move_base action client, /battery/state, ~state, ~on_failure, ~return_home_percentage,
    TF map -> base_link, ...), plus:

    Parameters (private)
      ~goal_yaw (str, "toward_next"): "toward_next" = each goal faces the next waypoint (the file's
        yaw is ignored; the original's file has yaw 1 rad on return passes, a defect), "file" = use
        the file's yaw_rad
      ~localized_topic (str, "/amcl/localized"): AMCL's verdict; while it is false (after having been
        true: a kidnap) the route pauses with the goal held and the robot stopped, see the base class
    Home = the robot's map pose when the route starts (with AMCL on the saved map: the spawn pose).
    """

    NAME = "map_waypoint_navigator"
    DEFAULT_LOCALIZED_TOPIC = "/amcl/localized"

    def __init__(self):
        self.goal_yaw = str(rospy.get_param("~goal_yaw", "toward_next"))
        if self.goal_yaw not in GOAL_YAW_MODES:
            raise NavigatorStartError(f"~goal_yaw must be one of {GOAL_YAW_MODES}, got {self.goal_yaw!r}")
        super().__init__()

    def load_route(self, path: str) -> list:
        return load_map_waypoints(path)

    def make_goals(self, waypoints: list) -> List[MapWaypoint]:
        return map_goals(waypoints, self.goal_yaw)
