"""Arm-plant contacts (robot/arm_contacts.py, farm/plant_obstacles.py): a hand-built plant, the arm's
link capsules placed by hand and by the UR5e's forward kinematics through SimulatedArm."""
import pathlib

import numpy as np
import pytest

from cottonsim_common.kinematics.arm_capsules import ARM_LINKS
from cottonsim_world.farm.model import Plant, PlantModel, PlantSkeleton
from cottonsim_world.farm.plant_obstacles import PlantObstacles
from cottonsim_world.robot.arm_contacts import ArmContactConfig, ArmContactCounter
from cottonsim_world.robot.arm_tracker import ArmControllerConfig
from cottonsim_world.robot.boll_store import BollFieldStore
from cottonsim_world.robot.sim_arm import SimulatedArm
from cottonsim_world.robot.urdf_model import UrdfModel
from cottonsim_world.robot.vacuum import VacuumConfig

URDF = pathlib.Path(__file__).resolve().parents[3] / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf"
FAR = np.array([50.0, 50.0, 5.0])
FOREARM = ARM_LINKS.index("forearm")


def hand_plant(plant_id=0, x=0.0, y=0.0, yaw=0.0):
    """A 1 m stem (radius 1 cm), one branch from (0, 0, 0.5) to (0.3, 0, 0.6), one leaf of 5 cm at (0, 0.25, 0.8)."""
    skeleton = PlantSkeleton(
        stem_start_m=np.array([[0.0, 0.0, 0.0]]), stem_end_m=np.array([[0.0, 0.0, 1.0]]), stem_radius_m=np.array([0.01]),
        branch_start_m=np.array([[0.0, 0.0, 0.5]]), branch_end_m=np.array([[0.3, 0.0, 0.6]]),
        branch_radius_m=np.array([0.006]),
        leaf_centre_m=np.array([[0.0, 0.25, 0.8]]), leaf_radius_m=np.array([0.05]))
    model = PlantModel({}, [], np.zeros((0, 3)), np.zeros(0), 1.0, 0.7, skeleton)
    return Plant(plant_id, 0, plant_id, x, y, yaw, model)


def arm_with(link, start, end):
    """Every link far away except `link`, which runs start -> end (world)."""
    s = np.tile(FAR, (len(ARM_LINKS), 1))
    e = s + [0.0, 0.0, 0.1]
    s[link], e[link] = start, end
    return s, e


def counter(*plants, **config):
    return ArmContactCounter(PlantObstacles.from_plants(plants), ArmContactConfig(**config))


def test_a_link_through_the_stem_is_a_stem_contact_one_beside_it_is_not():
    c = counter(hand_plant())
    assert c.update(0.0, *arm_with(FOREARM, [0.1, -0.3, 0.3], [0.1, 0.3, 0.3])) == []   # 10 cm beside the stem
    events = c.update(0.1, *arm_with(FOREARM, [-0.3, 0.0, 0.3], [0.3, 0.0, 0.3]))      # through the stem
    assert [(e.kind, e.part, e.link, e.plant_id) for e in events] == [("stem", "stem", "forearm", 0)]
    assert events[0].depth_m == pytest.approx(0.038 + 0.01)
    assert events[0].point_m == pytest.approx((0.0, 0.0, 0.3))
    assert c.totals == {"stem": 1, "leaf": 0} and c.plants_touched == {0}


def test_the_link_radius_counts_a_graze_and_a_branch_is_woody():
    c = counter(hand_plant())
    # the forearm (radius 38 mm) passes 40 mm from the stem axis: 2 mm overlap with the 10 mm stem
    graze = c.update(0.0, *arm_with(FOREARM, [0.04, -0.3, 0.2], [0.04, 0.3, 0.2]))
    assert [e.part for e in graze] == ["stem"] and graze[0].depth_m == pytest.approx(0.008)
    c2 = counter(hand_plant())
    across_branch = c2.update(0.0, *arm_with(FOREARM, [0.2, -0.3, 0.567], [0.2, 0.3, 0.567]))
    assert [(e.kind, e.part) for e in across_branch] == [("stem", "branch")]


def test_leaves_are_counted_as_leaf_contacts():
    c = counter(hand_plant())
    events = c.update(0.0, *arm_with(ARM_LINKS.index("nozzle"), [0.0, 0.4, 0.8], [0.0, 0.28, 0.8]))
    assert [(e.kind, e.link) for e in events] == [("leaf", "nozzle")]
    assert c.totals == {"stem": 0, "leaf": 1}


def test_an_episode_counts_once_and_a_new_touch_after_rearm_counts_again():
    c = counter(hand_plant(), rearm_s=0.1)
    through = arm_with(FOREARM, [-0.3, 0.0, 0.3], [0.3, 0.0, 0.3])
    apart = arm_with(FOREARM, [-0.3, 0.5, 0.3], [0.3, 0.5, 0.3])
    counts = [len(c.update(t, *through)) for t in np.arange(0.0, 0.5, 0.01)]
    assert counts[0] == 1 and sum(counts) == 1
    c.update(0.55, *apart)
    assert len(c.update(0.58, *through)) == 0          # apart for 0.08 s <= rearm_s: the same touch
    c.update(0.6, *apart)
    assert len(c.update(0.75, *through)) == 1           # apart for longer: a new event
    assert c.totals["stem"] == 2


def test_each_link_and_plant_is_its_own_pair_and_far_plants_are_not_checked():
    c = counter(hand_plant(0), hand_plant(1, x=0.5), hand_plant(2, x=10.0))
    start, end = arm_with(FOREARM, [-0.3, 0.0, 0.3], [0.8, 0.0, 0.3])
    start[ARM_LINKS.index("upper_arm")], end[ARM_LINKS.index("upper_arm")] = [0.5, -0.3, 0.2], [0.5, 0.3, 0.2]
    events = c.update(0.0, start, end)
    assert sorted((e.link, e.plant_id) for e in events) == [("forearm", 0), ("forearm", 1), ("upper_arm", 1)]
    assert c.plants_touched == {0, 1}


def test_plants_are_placed_by_position_and_yaw():
    obs = PlantObstacles.from_plants([hand_plant(3, x=2.0, y=1.0, yaw=np.pi / 2)])
    assert obs.woody_end_m[1] == pytest.approx([2.0, 1.3, 0.6])          # the branch turned to +y
    assert obs.leaf_centre_m[0] == pytest.approx([1.75, 1.0, 0.8])
    assert obs.plants_near([2.2, 1.0, 0.5], 0.0).tolist() == [3]
    assert obs.plants_near([3.0, 1.0, 0.5], 0.2).tolist() == []
    assert obs.woody_capsules([3]).names == ("stem/3", "branch/3")


def test_bad_input_is_refused():
    c = counter(hand_plant())
    with pytest.raises(ValueError, match="NaN"):
        c.update(0.0, *arm_with(FOREARM, [np.nan, 0, 0], [0, 0, 0]))
    with pytest.raises(ValueError, match="rearm_s"):
        ArmContactConfig(rearm_s=-1.0)
    with pytest.raises(ValueError, match="PlantObstacles"):
        ArmContactCounter("plants")


def test_the_simulated_arm_counts_its_forward_kinematics_against_the_plant():
    """Stowed over the base the arm touches nothing; stretched out sideways it crosses a stem beside the robot."""
    urdf = UrdfModel.from_file(URDF)
    plant = hand_plant(0, x=0.35, y=0.7)          # 0.7 m left of the arm base (base_link (0.345, 0, 0.251))
    world_T_base = np.eye(4)

    def events_at(q):
        contacts = counter(plant)
        arm = SimulatedArm(urdf, "ur5e_", q, ArmControllerConfig(), VacuumConfig(), BollFieldStore.of_plants([plant]),
                           "base_link", contacts)
        arm.step(0.005, 0.005, lambda: world_T_base)
        return arm, arm.take_contact_events()

    assert events_at([0.0, -2.2, 2.4, -1.77, -1.57, 0.0])[1] == []
    # pan pi, the rest 0: upper arm and forearm horizontal at shoulder height along the arm base's +x,
    # which is base_link's +y (the arm base is turned by pi/2)
    arm, events = events_at([np.pi, 0.0, 0.0, 0.0, 0.0, 0.0])
    start, end = arm.link_capsules(world_T_base)
    assert start[3:5, 2] == pytest.approx([0.251 + 0.1625] * 2, abs=1e-6)
    assert end[4, 1] > 0.7 > start[2, 1]
    assert {(e.kind, e.link, e.plant_id) for e in events} == {("stem", "forearm", 0)}
    assert arm.take_contact_events() == []
