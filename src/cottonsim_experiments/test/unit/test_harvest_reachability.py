"""Reachability of bolls from the route (harvest/reachability.py) on hand-built plants beside one lane."""
import math
import pathlib
from types import SimpleNamespace

import numpy as np
import pytest

from cottonsim_experiments.harvest.reachability import (ReachabilityConfig, farm_reachability, lane_facing,
                                                        lane_stops, reach_boll, robot_geometry_from_urdf)
from cottonsim_manipulation.planning.approach import ApproachConfig
from cottonsim_world.farm.model import Lane, Plant, PlantModel, PlantSkeleton
from cottonsim_world.farm.plant_obstacles import PlantObstacles

URDF = pathlib.Path(__file__).resolve().parents[3] / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf"
LANE = Lane(0, 0.0, 0.0, 2.0)          # along world y at x = 0, plants 0.9 m east of it


@pytest.fixture(scope="module")
def robot():
    return robot_geometry_from_urdf(URDF.read_text())


def plant(plant_id, x, y, bolls_local=(), stem_radius=0.01, height=1.0):
    skeleton = PlantSkeleton(np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, height]]), np.array([stem_radius]),
                             np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)), np.zeros(0))
    centres = np.array(bolls_local, dtype=float).reshape(-1, 3)
    model = PlantModel({}, [], centres, np.full(len(centres), 0.025), height, 0.7, skeleton)
    return Plant(plant_id, 0, plant_id, x, y, 0.0, model)


def study(roll_samples, **approach):
    return ReachabilityConfig(approach=ApproachConfig(roll_samples=roll_samples, **approach))


def judge(robot, boll_world, outward, plants, config=study(8)):
    stops = lane_stops([LANE], config.stop_spacing_m)
    return reach_boll(0, boll_world, outward, stops, PlantObstacles.from_plants(plants), robot, config)


def test_lane_stops_run_along_the_lane_every_spacing():
    stops = lane_stops([LANE, Lane(1, 3.0, 0.0, 0.25)], 0.1, yaw_rad=-math.pi / 2)
    assert [round(s.y_m, 6) for s in stops if s.lane_index == 0] == [round(0.1 * k, 6) for k in range(21)]
    assert [round(s.y_m, 6) for s in stops if s.lane_index == 1] == [0.0, 0.1, 0.2]
    assert {s.x_m for s in stops if s.lane_index == 1} == {3.0} and {s.yaw_rad for s in stops} == {-math.pi / 2}


def test_a_boll_on_the_lane_side_of_a_plant_beside_the_lane_is_reachable(robot):
    p = plant(0, 0.9, 1.0, [(-0.15, 0.0, 0.5)])
    verdict = judge(robot, (0.75, 1.0, 0.5), (-1.0, 0.0, 0.0), [p])
    assert verdict.reachable and verdict.stop.lane_index == 0
    assert abs(verdict.stop.y_m + 0.345 - 1.0) < 0.7              # from a stop near the boll (arm 0.345 ahead)
    assert verdict.q_grasp_rad.shape == (6,)


def test_a_boll_far_from_every_lane_has_no_stop_in_range(robot):
    assert judge(robot, (3.0, 1.0, 0.5), (-1.0, 0.0, 0.0), []).reason == "no_stop_in_range"


def test_a_boll_above_the_arms_reach_has_no_ik(robot):
    assert judge(robot, (0.75, 1.0, 2.5), (-1.0, 0.0, 0.0), []).reason == "no_ik"


def test_a_thick_stem_in_front_of_the_boll_makes_it_unreachable_by_collision(robot):
    # a 2 m tall, 16 cm thick stem 12 cm on the lane side of the boll blocks every approach along its outward
    blocker = plant(1, 0.63, 1.0, stem_radius=0.08, height=2.0)
    free = judge(robot, (0.75, 1.0, 0.5), (-1.0, 0.0, 0.0), [plant(0, 0.9, 1.0)])
    blocked = judge(robot, (0.75, 1.0, 0.5), (-1.0, 0.0, 0.0), [plant(0, 0.9, 1.0), blocker])
    assert free.reachable and blocked.reason == "collision"


def test_a_boll_facing_along_the_row_needs_the_planners_approach_turned_towards_the_lane(robot):
    # the boll faces the next plant (+y), whose 8 cm thick stem stands 14 cm ahead of it
    plants = [plant(0, 0.9, 1.0), plant(1, 0.85, 1.19, stem_radius=0.04, height=2.0)]
    straight = judge(robot, (0.85, 1.05, 0.5), (0.0, 1.0, 0.0), plants, study(8, yaw_samples_rad=(0.0,)))
    turned = judge(robot, (0.85, 1.05, 0.5), (0.0, 1.0, 0.0), plants)          # the planner's yaw samples
    assert not straight.reachable and turned.reachable


def test_lane_facing_halves():
    lanes = [LANE]
    assert lane_facing((0.8, 1.0, 0.5), (0.9, 1.0), lanes)          # west of the stem, the lane is west
    assert not lane_facing((1.0, 1.0, 0.5), (0.9, 1.0), lanes)      # east half: no lane there
    assert not lane_facing((0.8, 1.0, 0.5), (3.0, 1.0), lanes)      # the lane is too far away


def test_farm_reachability_numbers_bolls_as_the_simulator_does(robot):
    plants = [plant(0, 0.9, 0.5, [(-0.15, 0.0, 0.5), (0.15, 0.0, 0.5)]), plant(1, 0.9, 1.5, [(-0.15, 0.1, 0.6)])]
    farm = SimpleNamespace(plants=plants)
    verdicts = farm_reachability(farm, [LANE], robot, study(6))
    assert [v.boll_id for v in verdicts] == [0, 1, 2]
    assert verdicts[0].reachable and verdicts[2].reachable
    assert not verdicts[1].reachable                               # behind its stem, facing away from the lane


def test_bad_config_and_input_are_refused(robot):
    with pytest.raises(ValueError, match="stop_spacing_m"):
        ReachabilityConfig(stop_spacing_m=0.0)
    with pytest.raises(ValueError, match="max_reach_m"):
        ReachabilityConfig(max_reach_m=float("nan"))
    with pytest.raises(ValueError, match="approach must be an ApproachConfig"):
        ReachabilityConfig(approach={"roll_samples": 8})
    with pytest.raises(ValueError, match="finite"):
        judge(robot, (np.nan, 1.0, 0.5), (-1.0, 0.0, 0.0), [])
