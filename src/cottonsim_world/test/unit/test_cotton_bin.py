"""The cotton bin: the URDF's cotton_bin, the vacuum's bin opening and the pick cycle's bin joints agree,
and a boll released over the bin goes into it while one released elsewhere drops."""
import pathlib

import numpy as np

from cottonsim_common.kinematics.ur5e import forward_kinematics
from cottonsim_manipulation.harvest.pick_cycle import PickCycleConfig
from cottonsim_manipulation.planning.collision import ArmCollisionModel
from cottonsim_manipulation.planning.robot_body import body_boxes_from_urdf
from cottonsim_world.farm.model import Plant, PlantModel
from cottonsim_world.robot.arm_tracker import ArmControllerConfig
from cottonsim_world.robot.boll_store import DROPPED, IN_BIN, BollFieldStore
from cottonsim_world.robot.sim_arm import SimulatedArm
from cottonsim_world.robot.urdf_model import UrdfModel
from cottonsim_world.robot.vacuum import VacuumConfig

URDF = pathlib.Path(__file__).resolve().parents[3] / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf"
STOW = (0.0, -2.2, 2.4, -1.77, -1.57, 0.0)


def tip_in_base_link(urdf, q):
    return (urdf.fixed_transform("base_link", "ur5e_base") @ forward_kinematics(q)
            @ urdf.fixed_transform("ur5e_tool0", "ur5e_nozzle_tip"))


def test_the_bin_joints_put_the_nozzle_over_the_urdf_bin_inside_the_release_box_and_clear_of_the_robot():
    urdf = UrdfModel.from_file(URDF)
    tip = tip_in_base_link(urdf, PickCycleConfig().bin_joints_rad)
    vacuum = VacuumConfig()
    assert np.all(np.abs(tip[:3, 3] - vacuum.bin_centre_m) <= vacuum.bin_half_size_m)
    assert tip[:3, 2] @ [0.0, 0.0, -1.0] > 0.99                        # pointing down
    floor = urdf.fixed_transform("base_link", "cotton_bin")[:3, 3]      # the bin's floor centre
    assert np.abs(tip[:2, 3] - floor[:2]).max() < 0.01 and 0.10 < tip[2, 3] - (floor[2] + 0.12) < 0.175
    # the release box lies inside the bin's walls (0.22 x 0.40 m outside, 5 mm thick) and above its floor
    assert np.all(np.abs(np.array(vacuum.bin_centre_m[:2]) - floor[:2]) + vacuum.bin_half_size_m[:2] <= [0.105, 0.195])
    assert vacuum.bin_centre_m[2] - vacuum.bin_half_size_m[2] > floor[2]
    body = body_boxes_from_urdf(URDF.read_text())
    assert any(name.startswith("cotton_bin/") for name in body.names)
    assert ArmCollisionModel(body=body).contacts(np.array([PickCycleConfig().bin_joints_rad])) == []


def test_a_boll_released_over_the_bin_goes_in_one_released_elsewhere_drops():
    urdf = UrdfModel.from_file(URDF)
    world_T_base = np.eye(4)
    outcomes = []
    for q in (PickCycleConfig().bin_joints_rad, STOW):
        model = PlantModel({}, [], np.array([[0.0, 0.0, 0.5]]), np.array([0.025]), 1.0, 0.6)
        store = BollFieldStore.of_plants([Plant(0, 0, 0, 3.0, 3.0, 0.0, model)])
        arm = SimulatedArm(urdf, "ur5e_", q, ArmControllerConfig(), VacuumConfig(), store)
        store.attach(0)                                   # as if captured: the nozzle holds boll 0
        arm.nozzle.held_id, arm.nozzle._tip_T_boll = 0, np.eye(4)
        message = arm.switch_vacuum(False, world_T_base)
        outcomes.append((store.state(0), "into the bin" in message))
    assert outcomes == [(IN_BIN, True), (DROPPED, False)]
