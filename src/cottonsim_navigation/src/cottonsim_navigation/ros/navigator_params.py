"""The waypoint navigators' private parameters, read and checked once at start.

``read_navigator_params`` returns them as a ``NavigatorParams``; a bad value
raises ``NavigatorStartError`` naming the parameter (the node exits non-zero).

Parameters (private)
  ~waypoints_file (str, required): the route file
  ~on_failure (str, "skip"): after an aborted goal, "skip" to the next one or "stop" the route
  ~return_home_percentage (float, 40.0): battery charge [%] at which the robot drives Home; 0 = never
  ~battery_topic (str, "/battery/state")
  ~move_base_action (str, "move_base"): action namespace
  ~goal_frame (str, "map"), ~robot_frame (str, "base_link")
  ~server_timeout_s (float, 60.0): wall time to wait for the move_base server; 0 = forever
  ~goal_timeout_s (float, 300.0): sim time after which a goal counts as aborted (cancelled); 0 = never
  ~loop_hz (float, 10.0): decision loop rate [Hz, sim time]
  ~localized_topic (str, the navigator's default, "" = none): the localiser's verdicts (std_msgs/Bool)
  ~pass_through_radius_m (float, 0.0): a waypoint where the route goes on straight (turn <=
    ~pass_through_max_turn_rad) counts as reached once the robot (TF) is this close, and the next
    goal is sent at once (preempting), so the robot drives through instead of stopping; 0 = off
  ~pass_through_max_turn_rad (float, 0.35 = 20 deg): the largest turn a pass-through waypoint may have
  ~boll_halt/enabled (bool, true), ~boll_halt/dwell_s (float, 2.0 s), ~boll_halt/rearm_distance_m
    (float, 0.7 m), ~boll_halt/min_gap_s (float, 1.0 s), ~boll_halt/max_age_s (float, 1.0 s): the halt at
    bolls (waypoints.boll_halt.BollHaltConfig; config/boll_halt.yaml); the way Home never halts
  ~bolls_in_reach_topic (str, "/cotton_eye/bolls_in_reach"): the boll detectors' verdicts (with the halt)
  ~route_hold/max_age_s (float, 1.0 s): a hold request on ~hold_topic older than this releases the route
  ~hold_topic (str, "" = none): route hold requests (std_msgs/Bool)
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import rospy

from cottonsim_common.ros.params import config_from_params
from cottonsim_navigation.waypoints.boll_halt import BollHaltConfig
from cottonsim_navigation.waypoints.follower import FollowerConfig
from cottonsim_navigation.waypoints.route_hold import RouteHoldConfig


class NavigatorStartError(RuntimeError):
    """The navigator cannot start (bad parameter, unreadable waypoint file); the node exits non-zero."""


@dataclass(frozen=True)
class NavigatorParams:
    """The checked parameters (module docstring); the topic and frame names as given."""

    waypoints_file: str
    return_home_percentage: float
    battery_topic: str
    action_ns: str
    goal_frame: str
    robot_frame: str
    server_timeout_s: float
    goal_timeout_s: float
    loop_hz: float
    pass_through_max_turn_rad: float
    localized_topic: str
    bolls_in_reach_topic: str
    hold_topic: str
    follower_config: FollowerConfig
    halt_config: BollHaltConfig
    route_hold_config: RouteHoldConfig


def _check_range(name: str, value: float, low: float, high: float, what: str) -> float:
    if not (math.isfinite(value) and low <= value <= high):
        raise NavigatorStartError(f"~{name} must be {what}, got {value}")
    return value


def read_navigator_params(node_name: str, default_localized_topic: str) -> NavigatorParams:
    """The navigator's private parameters (module docstring); NavigatorStartError naming a bad one."""
    def get(name, default, kind=float):
        return kind(rospy.get_param(f"~{name}", default))

    try:
        follower_config = FollowerConfig(on_failure=get("on_failure", "skip", str),
                                         pass_through_radius_m=get("pass_through_radius_m", 0.0))
    except ValueError as exc:
        raise NavigatorStartError(f"~{str(exc).split(' ')[0]}: {exc}") from None
    return_home_percentage = _check_range("return_home_percentage", get("return_home_percentage", 40.0), 0.0, 100.0,
                                          "a percentage in [0, 100]")
    if 0.0 < return_home_percentage < 1.0:
        rospy.logwarn("%s: ~return_home_percentage %.3f is in percent (40 = 40 %%), not a fraction",
                      node_name, return_home_percentage)
    loop_hz = get("loop_hz", 10.0)
    if not (math.isfinite(loop_hz) and loop_hz > 0.0):
        raise NavigatorStartError(f"~loop_hz must be > 0, got {loop_hz}")
    waypoints_file = get("waypoints_file", "", str)
    if not waypoints_file:
        raise NavigatorStartError("~waypoints_file is not set")
    try:
        halt_config = config_from_params(BollHaltConfig, "~boll_halt/")
        route_hold_config = config_from_params(RouteHoldConfig, "~route_hold/")
    except ValueError as exc:
        raise NavigatorStartError(str(exc)) from None
    return NavigatorParams(
        waypoints_file=waypoints_file, return_home_percentage=return_home_percentage,
        battery_topic=get("battery_topic", "/battery/state", str), action_ns=get("move_base_action", "move_base", str),
        goal_frame=get("goal_frame", "map", str), robot_frame=get("robot_frame", "base_link", str),
        server_timeout_s=_check_range("server_timeout_s", get("server_timeout_s", 60.0), 0.0, math.inf,
                                      "finite and >= 0"),
        goal_timeout_s=_check_range("goal_timeout_s", get("goal_timeout_s", 300.0), 0.0, math.inf, "finite and >= 0"),
        loop_hz=loop_hz,
        pass_through_max_turn_rad=_check_range("pass_through_max_turn_rad",
                                               get("pass_through_max_turn_rad", math.radians(20.0)), 0.0, math.pi,
                                               "in [0, pi]"),
        localized_topic=get("localized_topic", default_localized_topic, str),
        bolls_in_reach_topic=get("bolls_in_reach_topic", "/cotton_eye/bolls_in_reach", str),
        hold_topic=get("hold_topic", "", str),
        follower_config=follower_config, halt_config=halt_config, route_hold_config=route_hold_config)
