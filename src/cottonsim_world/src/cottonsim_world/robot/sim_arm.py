"""The simulated UR5e with its controller and vacuum nozzle, as the Simulator steps it.

``SimulatedArm`` puts together the joints (``Ur5eArm``), the trajectory
controller (``ArmTrajectoryTracker``, run at every physics step while it has
something to do), the plain position follower of /arm_controller/command
(run every ARM_PERIOD_S until at rest) and the vacuum nozzle (its capture
rule applied at every physics step while the vacuum is on or a boll is held).
The nozzle tip's pose comes from the robot's pose in the world, the URDF's
fixed transforms base_link -> ur5e_base and ur5e_tool0 -> ur5e_nozzle_tip and
the UR5e's forward kinematics. With an ``ArmContactCounter`` the arm's link
capsules are checked against the plants after each step (robot/arm_contacts.py).
"""
from __future__ import annotations

from typing import Callable, Hashable, List, Optional, Sequence

import numpy as np

from cottonsim_common.kinematics.arm_capsules import arm_capsule_segments
from cottonsim_world.robot.arm_contacts import ArmContactCounter, ArmContactEvent
from cottonsim_world.robot.arm_goal import ArmLimits, TrajectoryGoal, ValidTrajectory, validate_goal
from cottonsim_world.robot.arm_tracker import ArmControllerConfig, ArmTrajectoryTracker
from cottonsim_world.robot.boll_store import BollStore
from cottonsim_world.robot.ur5e import JOINT_NAMES, Ur5eArm, forward_kinematics
from cottonsim_world.robot.urdf_model import UrdfModel
from cottonsim_world.robot.vacuum import VacuumConfig, VacuumNozzle
from cottonsim_world.simulator_config import ARM_PERIOD_S

NOZZLE_TIP_LINK = "nozzle_tip"   # after the arm's prefix: ur5e_nozzle_tip


class SimulatedArm:
    """The arm, its controller and its nozzle (see the module docstring)."""

    def __init__(self, urdf: UrdfModel, prefix: str, initial_positions_rad: Sequence[float],
                 controller: ArmControllerConfig, vacuum: VacuumConfig, bolls: BollStore,
                 base_frame: str = "base_link", contacts: Optional[ArmContactCounter] = None):
        self.arm = Ur5eArm.from_urdf(urdf, prefix, initial_positions=initial_positions_rad)
        self.joint_names = tuple(prefix + name for name in JOINT_NAMES)
        self.tracker = ArmTrajectoryTracker(self.arm, controller, self.joint_names)
        self.limits = ArmLimits(self.joint_names,
                                np.array([lim.lower for lim in self.arm.limits]),
                                np.array([lim.upper for lim in self.arm.limits]),
                                np.array([lim.velocity for lim in self.arm.limits]))
        self.base_T_arm = urdf.fixed_transform(base_frame, prefix + "base")
        self.tool0_T_tip = urdf.fixed_transform(prefix + "tool0", prefix + NOZZLE_TIP_LINK)
        self.nozzle = VacuumNozzle(bolls, vacuum)
        self._follower_dt_s = 0.0
        self._follower_idle = False     # at target and still: skip the follower until the next command
        self.contacts = contacts
        self._arm_shape = contacts.config.arm_shape() if contacts is not None else None
        self._contact_events: List[ArmContactEvent] = []
        self._capsules_at = None        # (joints, capsules in the arm's base frame) of the last check

    # ------------------------------------------------------------------ commands
    def command_positions(self, positions_rad: Sequence[float]) -> np.ndarray:
        """/arm_controller/command: position targets for the follower; a running goal is aborted."""
        self.tracker.supersede("aborted: a position command on /arm_controller/command took the arm over")
        clamped = self.arm.command(positions_rad)
        self._follower_idle = False
        return clamped

    def accept_goal(self, goal_id: Hashable, goal: TrajectoryGoal, now_s: float) -> ValidTrajectory:
        """Validate the goal against the arm's state now and track it; GoalRejected with the reason."""
        trajectory = validate_goal(goal, self.limits, now_s, self.arm.positions, self.arm.velocities,
                                   self.tracker.config.goal_defaults())
        self.tracker.accept(goal_id, trajectory)
        return trajectory

    def cancel_goal(self, goal_id: Hashable, now_s: float) -> bool:
        """Brake to rest; the goal ends 'canceled' at rest. False when goal_id is not the running goal."""
        return self.tracker.cancel(goal_id, now_s)

    def switch_vacuum(self, on: bool, world_T_base: np.ndarray) -> str:
        return self.nozzle.switch(on, self.tip_pose(world_T_base), world_T_base)

    # ------------------------------------------------------------------ state
    def tip_pose(self, world_T_base: np.ndarray) -> np.ndarray:
        """4x4 pose of the nozzle tip in the world at the current joints."""
        return world_T_base @ self.base_T_arm @ forward_kinematics(self.arm.positions) @ self.tool0_T_tip

    def link_capsules(self, world_T_base: np.ndarray):
        """The arm's link capsules (ARM_LINKS, as the contact counter shapes them) at the current joints:
        segment ends (9, 3), (9, 3) in the world."""
        start, end, _, _ = self._arm_frame_capsules()
        world_T_arm = world_T_base @ self.base_T_arm
        rot, trans = world_T_arm[:3, :3], world_T_arm[:3, 3]
        return start @ rot.T + trans, end @ rot.T + trans

    def _arm_frame_capsules(self):
        """Capsule ends in the arm's base frame and their bounding sphere (centre, radius incl. the link
        radii) at the current joints; kept until the joints change."""
        q = self.arm.positions
        if self._capsules_at is None or not np.array_equal(q, self._capsules_at[0]):
            start, end = arm_capsule_segments(q, self._arm_shape)
            points = np.concatenate([start[0], end[0]])
            centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
            radius = float(np.linalg.norm(points - centre, axis=1).max()) + float(self._arm_shape.radii_m.max())
            self._capsules_at = (q, (start[0], end[0], centre, radius))
        return self._capsules_at[1]

    def _check_contacts(self, now_s: float, world_T_base: np.ndarray) -> None:
        """One contact check: the broad phase on the capsules' bounding sphere first (the arm is mostly
        away from every plant), the counter's own checks when a plant is near."""
        _, _, centre, radius = self._arm_frame_capsules()
        world_T_arm = world_T_base @ self.base_T_arm
        if not self.contacts.near_plants(world_T_arm[:3, :3] @ centre + world_T_arm[:3, 3], radius):
            self.contacts.update_apart(now_s)
            return
        self._contact_events.extend(self.contacts.update(now_s, *self.link_capsules(world_T_base)))

    # ------------------------------------------------------------------ stepping
    def step(self, now_s: float, dt_s: float, world_T_base: Callable[[], np.ndarray]) -> Optional[int]:
        """One physics step of dt_s ending at now_s; the id of a boll captured in it, if any."""
        if self.tracker.busy:
            self.tracker.step(now_s, dt_s)
            self._follower_dt_s = 0.0
            self._follower_idle = False
        else:
            self._follower_dt_s += dt_s
            if self._follower_dt_s >= ARM_PERIOD_S - 1e-12:
                if not self._follower_idle:
                    if not self.arm.at_target() or np.any(self.arm.velocities):
                        self.arm.step(self._follower_dt_s)
                    else:
                        self._follower_idle = True
                self._follower_dt_s = 0.0
        if self.contacts is not None and self.contacts.due(now_s):
            self._check_contacts(now_s, world_T_base())
        nozzle = self.nozzle
        if nozzle.on or nozzle.held_id is not None:
            return nozzle.step(self.tip_pose(world_T_base()))
        return None

    def take_contact_events(self) -> List[ArmContactEvent]:
        """The arm-plant contact events since the last call (none without a counter)."""
        events, self._contact_events = self._contact_events, []
        return events
