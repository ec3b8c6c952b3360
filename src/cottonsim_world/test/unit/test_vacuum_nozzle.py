"""The vacuum nozzle (robot/vacuum.py), its view of the boll field (robot/boll_store.py) and a pick through
SimulatedArm: a trajectory goal brings the nozzle to a boll, the vacuum captures it, the boll travels with
the tool and goes into the bin."""
import math
import pathlib

import numpy as np
import pytest

from cottonsim_common.kinematics.ur5e import inverse_kinematics
from cottonsim_manipulation.planning.approach import tool_rotations
from cottonsim_world.farm.model import Plant, PlantModel
from cottonsim_world.robot.arm_goal import TrajectoryGoal, TrajectoryPoint
from cottonsim_world.robot.arm_tracker import ArmControllerConfig
from cottonsim_world.robot.boll_store import DROPPED, HELD, IN_BIN, OPEN, BollFieldStore
from cottonsim_world.robot.sim_arm import SimulatedArm
from cottonsim_world.robot.urdf_model import UrdfModel
from cottonsim_world.robot.vacuum import VacuumConfig, VacuumNozzle

URDF = pathlib.Path(__file__).resolve().parents[3] / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf"
HOME = np.array([0.0, -2.2, 2.4, -1.77, -1.57, 0.0])
NAMES = tuple("ur5e_" + n for n in ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                                    "wrist_2_joint", "wrist_3_joint"))
DT = 0.005


def plant(x, y, bolls_local, plant_id=0):
    model = PlantModel({}, [], np.array(bolls_local, dtype=float), np.full(len(bolls_local), 0.025), 1.0, 0.6)
    return Plant(plant_id, 0, plant_id, x, y, 0.0, model)


def field_store(*plants):
    """The nozzle's view (BollFieldStore) of a boll field made of these plants."""
    return BollFieldStore.of_plants(plants)


def pose(position, z_axis):
    """A 4x4 pose at position whose z axis is z_axis."""
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = tool_rotations(np.asarray(z_axis, dtype=float), np.zeros(1))[0], position
    return t


def test_store_views_bolls_with_their_outward_direction_and_refuses_bad_transitions():
    store = field_store(plant(1.0, 2.0, [[0.2, 0.0, 0.5], [0.0, -0.1, 0.7]]), plant(3.0, 2.0, [[0, 0, 0.4]], 1))
    assert len(store) == 3
    view = store.nearest_open([1.19, 2.0, 0.52])
    assert view.boll_id == 0 and np.allclose(view.centre_m, [1.2, 2.0, 0.5]) and np.allclose(view.outward, [1, 0, 0])
    assert np.allclose(store.nearest_open([1.0, 1.9, 0.7]).outward, [0, -1, 0])
    assert np.allclose(store.nearest_open([3.0, 2.0, 0.4]).outward, [1, 0, 0])   # on the stem axis: +x
    store.attach(0)
    assert store.state(0) == HELD and store.nearest_open([1.2, 2.0, 0.5]).boll_id != 0
    with pytest.raises(ValueError, match="boll 0 cannot be detached: it is HELD, not ON_PLANT"):
        store.attach(0)
    with pytest.raises(ValueError, match="boll 1 is open, not held"):
        store.release_into_bin(1)
    with pytest.raises(ValueError, match="unknown boll id 7"):
        store.attach(7)


@pytest.mark.parametrize("offset, axis, captured", [
    ((0.0, 0.0, 0.0), (-1, 0, 0), True),                   # tip on the centre, pointing into the boll
    ((0.0, 0.019, 0.0), (-1, 0, 0), True),                 # within the 2 cm capture radius
    ((0.0, 0.025, 0.0), (-1, 0, 0), False),                # too far
    ((0.0, 0.0, 0.0), (-math.cos(0.9), math.sin(0.9), 0), False),   # 52 deg off the inward direction
    ((0.0, 0.0, 0.0), (-math.cos(0.7), math.sin(0.7), 0), True),    # 40 deg: inside the 45 deg cone
])
def test_capture_rule_on_the_nozzle(offset, axis, captured):
    store = field_store(plant(1.0, 2.0, [[0.2, 0.0, 0.5]]))
    nozzle = VacuumNozzle(store, VacuumConfig())
    tip = pose(np.array([1.2, 2.0, 0.5]) + offset, axis)
    assert nozzle.step(tip) is None                 # vacuum off: nothing happens
    nozzle.switch(True, tip, np.eye(4))
    assert (nozzle.step(tip) == 0) is captured
    assert store.state(0) == (HELD if captured else OPEN)


def test_switching_off_without_a_capture_says_how_close_the_tip_came_and_why_it_missed():
    store = field_store(plant(1.0, 2.0, [[0.2, 0.0, 0.5]]))
    nozzle = VacuumNozzle(store, VacuumConfig())
    nozzle.switch(True, pose([1.3, 2.0, 0.5], [-1, 0, 0]), np.eye(4))
    for x in (1.3, 1.25, 1.21):                      # along the approach, 52 deg off the inward direction
        assert nozzle.step(pose([x, 2.0, 0.5], (-math.cos(0.9), math.sin(0.9), 0))) is None
    text = nozzle.switch(False, pose([1.3, 2.0, 0.5], [-1, 0, 0]), np.eye(4))
    assert "within 10.0 mm of boll 0, 52 deg off" in text and "misaligned" in text, text
    nozzle.switch(True, pose([1.3, 2.0, 0.5], [-1, 0, 0]), np.eye(4))
    nozzle.step(pose([1.25, 2.0, 0.5], [-1, 0, 0]))
    text = nozzle.switch(False, pose([1.3, 2.0, 0.5], [-1, 0, 0]), np.eye(4))
    assert "within 50.0 mm of boll 0" in text and "too far" in text, text
    nozzle.switch(True, pose([1.3, 2.0, 0.5], [-1, 0, 0]), np.eye(4))
    assert nozzle.switch(False, pose([1.3, 2.0, 0.5], [-1, 0, 0]), np.eye(4)) == "vacuum off"   # never stepped


def test_a_held_boll_travels_with_the_tool_and_is_released_into_the_bin_or_dropped():
    store = field_store(plant(1.0, 2.0, [[0.2, 0.0, 0.5], [0.2, 0.2, 0.5]]))
    cfg = VacuumConfig(bin_centre_m=(0.0, 0.0, 0.6), bin_half_size_m=(0.1, 0.1, 0.1))
    nozzle = VacuumNozzle(store, cfg)
    tip = pose([1.2, 2.01, 0.5], [-1, 0, 0])
    nozzle.switch(True, tip, np.eye(4))
    assert nozzle.step(tip) == 0
    moved = pose([0.5, 0.5, 1.0], [0, 0, -1])
    nozzle.step(moved)
    offset_before = np.array([1.2, 2.0, 0.5]) - tip[:3, 3]
    assert np.allclose(store.field.positions_m()[0] - moved[:3, 3], moved[:3, :3] @ tip[:3, :3].T @ offset_before)
    assert nozzle.step(pose([1.2, 2.2, 0.5], [-1, 0, 0])) is None      # holds one boll: no second capture
    base = np.eye(4)
    base[:3, 3] = [0.0, 0.0, 0.5]                    # the bin's opening is at z 1.1 in the world
    text = nozzle.switch(False, pose([0.05, 0.0, 1.15], [0, 0, -1]), base)
    assert store.state(0) == IN_BIN and "into the bin" in text and nozzle.held_id is None
    nozzle.switch(True, tip, base)
    assert nozzle.step(pose([1.2, 2.2, 0.5], [-1, -1, 0])) == 1
    text = nozzle.switch(False, pose([2.0, 2.0, 0.3], [-1, 0, 0]), base)
    assert store.state(1) == DROPPED and "dropped" in text
    assert np.allclose(store.field.positions_m()[1], [2.0, 2.0, 0.3], atol=0.02)


def test_vacuum_config_names_its_keys():
    with pytest.raises(ValueError, match="VacuumConfig.capture_radius_m"):
        VacuumConfig(capture_radius_m=-0.01)
    with pytest.raises(ValueError, match="VacuumConfig.bin_half_size_m"):
        VacuumConfig(bin_half_size_m=(0.1, 0.0, 0.1))


def _joints_for_tip(sim_arm, world_T_base, world_T_tip):
    """Arm joints that put the nozzle tip at world_T_tip (the IK of the flange pose), nearest HOME."""
    arm_T_tool0 = np.linalg.inv(world_T_base @ sim_arm.base_T_arm) @ world_T_tip @ np.linalg.inv(sim_arm.tool0_T_tip)
    result = inverse_kinematics(arm_T_tool0, HOME)
    assert result.ok, result.status
    return result.best


def _goal_to(q, duration_s):
    return TrajectoryGoal(NAMES, (TrajectoryPoint(tuple(q), (0.0,) * 6, (), duration_s),))


def test_a_pick_through_the_trajectory_controller_and_the_vacuum():
    urdf = UrdfModel.from_file(URDF)
    world_T_base = np.eye(4)
    world_T_base[:3, 3] = [5.0, 3.0, 0.13228]
    # a boll 0.75 m to the robot's left, 0.6 m above the ground; its plant's stem further left
    boll = np.array([5.4, 3.75, 0.6])
    store = field_store(plant(5.4, 4.0, [[0.0, -0.25, 0.6]]))
    sim_arm = SimulatedArm(urdf, "ur5e_", HOME, ArmControllerConfig(), VacuumConfig(), store)
    assert np.allclose(sim_arm.tip_pose(world_T_base),
                       world_T_base @ urdf.transform("base_link", "ur5e_nozzle_tip", dict(zip(NAMES, HOME))))
    q_pick = _joints_for_tip(sim_arm, world_T_base, pose(boll, [0, 1, 0]))
    sim_arm.switch_vacuum(True, world_T_base)
    sim_arm.accept_goal("pick", _goal_to(q_pick, 3.0), 0.0)
    t, captured_at = 0.0, None
    for _ in range(int(3.5 / DT)):
        t += DT
        if sim_arm.step(t, DT, lambda: world_T_base) is not None:
            captured_at = t
    assert [o.status for o in sim_arm.tracker.take_outcomes()] == ["succeeded"]
    assert store.state(0) == HELD and 2.5 < captured_at <= 3.5     # only when the tip got there
    # to the bin (its opening in base_link, VacuumConfig's default), pointing down, then vacuum off
    bin_tip = world_T_base @ pose(VacuumConfig().bin_centre_m, [0, 0, -1])
    q_bin = _joints_for_tip(sim_arm, world_T_base, bin_tip)
    sim_arm.accept_goal("to_bin", _goal_to(q_bin, 3.0), t)
    for _ in range(int(3.5 / DT)):
        t += DT
        sim_arm.step(t, DT, lambda: world_T_base)
    assert np.linalg.norm(store.field.positions_m()[0] - bin_tip[:3, 3]) < 0.03     # the boll came along
    assert "into the bin" in sim_arm.switch_vacuum(False, world_T_base) and store.state(0) == IN_BIN
