"""The simulated UR5e's ROS API in the simulator bridge: the trajectory action and the vacuum.

Action server
  /arm_controller/follow_joint_trajectory  cottonsim_msgs/FollowJointTrajectory (the fields and error codes of
      control_msgs/FollowJointTrajectory). A goal is validated against the arm's state when the simulation
      loop takes it: rejected (result error_code INVALID_JOINTS / INVALID_GOAL / OLD_HEADER_TIMESTAMP and the
      reason in error_string and the status text) or accepted and tracked at the physics rate. A new goal
      preempts the running one (its result: canceled, "preempted by goal ..."); a cancel brakes the arm to
      rest where it is and then ends the goal (canceled). Succeeded once every joint is within the goal
      tolerance after the last point's time, aborted (PATH_TOLERANCE_VIOLATED / GOAL_TOLERANCE_VIOLATED) when
      a tolerance is broken, or aborted when /arm_controller/command takes the arm over.
      Feedback every ~sim/arm_controller/feedback_period_s of sim time (desired, actual, error).
Service
  /arm_controller/vacuum                   std_srvs/SetBool: the vacuum nozzle on / off; off releases a held
                                           boll into the bin (tip over the bin) or drops it; message says which
Publication
  /arm_controller/vacuum/holding           std_msgs/Bool (latched): whether the nozzle holds a boll (the
                                           vacuum gripper's pressure switch), on every change
Every request is handed to the simulation loop, the only thread that touches the simulator
(``apply_inputs`` before a physics step, ``after_step`` after it).
"""
from __future__ import annotations

import threading
from typing import Dict, List

import actionlib
import rospy
from cottonsim_msgs.msg import FollowJointTrajectoryAction, FollowJointTrajectoryFeedback, FollowJointTrajectoryResult
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, SetBoolResponse
from trajectory_msgs.msg import JointTrajectoryPoint

from cottonsim_world.robot.arm_goal import GoalRejected, JointToleranceSpec, TrajectoryGoal, TrajectoryPoint
from cottonsim_common.ros import conversions as conv

ACTION_NAME = "/arm_controller/follow_joint_trajectory"


def goal_from_msg(msg) -> TrajectoryGoal:
    """The plain TrajectoryGoal of a FollowJointTrajectoryGoal message."""
    traj = msg.trajectory
    points = tuple(TrajectoryPoint(tuple(p.positions), tuple(p.velocities), tuple(p.accelerations),
                                   p.time_from_start.to_sec()) for p in traj.points)

    def tolerances(items):
        return tuple(JointToleranceSpec(t.name, t.position, t.velocity, t.acceleration) for t in items)

    return TrajectoryGoal(tuple(traj.joint_names), points, tolerances(msg.path_tolerance),
                          tolerances(msg.goal_tolerance), msg.goal_time_tolerance.to_sec(), traj.header.stamp.to_sec())


class ArmRosInterface:
    """The arm's action server, vacuum service and holding topic (see the module docstring)."""

    def __init__(self, sim):
        self.sim = sim
        self.arm = sim.arm_system
        self._lock = threading.Lock()
        self._jobs: List[list] = []             # [kind, payload, Event or None, answer]
        self._handles: Dict[str, object] = {}   # goal id -> actionlib goal handle of accepted goals
        self._next_feedback_s = 0.0
        self._holding = None
        self.holding_pub = rospy.Publisher("/arm_controller/vacuum/holding", Bool, queue_size=1, latch=True)
        self.server = actionlib.ActionServer(ACTION_NAME, FollowJointTrajectoryAction, self._on_goal,
                                             self._on_cancel, auto_start=False)
        self.server.start()
        rospy.Service("/arm_controller/vacuum", SetBool, self._on_vacuum)

    # ------------------------------------------------------------------ ROS threads
    def _on_goal(self, handle):
        with self._lock:
            self._jobs.append(["goal", handle, None, None])

    def _on_cancel(self, handle):
        with self._lock:
            self._jobs.append(["cancel", handle, None, None])

    def _on_vacuum(self, req):
        job = ["vacuum", bool(req.data), threading.Event(), None]
        with self._lock:
            self._jobs.append(job)
        if not job[2].wait(10.0):
            return SetBoolResponse(False, "the simulation loop did not take the request within 10 s (wall)")
        rospy.loginfo("sim_bridge: %s", job[3])
        return SetBoolResponse(True, job[3])

    # ------------------------------------------------------------------ simulation loop
    def apply_inputs(self) -> None:
        """Before a physics step: take the goals, cancels and vacuum switches that came in."""
        with self._lock:
            jobs, self._jobs = self._jobs, []
        for job in jobs:
            kind, payload = job[0], job[1]
            if kind == "goal":
                self._take_goal(payload)
            elif kind == "cancel":
                goal_id = payload.get_goal_id().id
                if goal_id in self._handles:
                    self.arm.cancel_goal(goal_id, self.sim.time_s)
            else:
                job[3] = self.arm.switch_vacuum(payload, self.sim.world_T_base())
                job[2].set()

    def _take_goal(self, handle) -> None:
        goal_id = handle.get_goal_id().id
        try:
            self.arm.accept_goal(goal_id, goal_from_msg(handle.get_goal()), self.sim.time_s)
        except GoalRejected as exc:
            rospy.logwarn("sim_bridge: trajectory goal rejected: %s", exc.reason)
            handle.set_rejected(FollowJointTrajectoryResult(error_code=exc.error_code, error_string=exc.reason),
                                exc.reason)
            return
        self._handles[goal_id] = handle
        handle.set_accepted()
        self._next_feedback_s = self.sim.time_s

    def after_step(self) -> None:
        """After a physics step: results of finished goals, feedback, the holding state."""
        for outcome in self.arm.tracker.take_outcomes():
            handle = self._handles.pop(outcome.goal_id, None)
            if handle is None:
                continue
            result = FollowJointTrajectoryResult(error_code=outcome.error_code, error_string=outcome.error_string)
            if outcome.status == "succeeded":
                handle.set_succeeded(result)
            elif outcome.status == "aborted":
                rospy.logwarn("sim_bridge: trajectory goal aborted: %s", outcome.error_string)
                handle.set_aborted(result, outcome.error_string)
            else:
                handle.set_canceled(result, outcome.error_string)
        now = self.sim.time_s
        goal_id = self.arm.tracker.active_goal
        state = self.arm.tracker.last_state
        if goal_id in self._handles and state is not None and now >= self._next_feedback_s - 1e-9:
            self._next_feedback_s = now + self.arm.tracker.config.feedback_period_s
            self._handles[goal_id].publish_feedback(self._feedback(state))
        holding = self.arm.nozzle.held_id is not None
        if holding != self._holding:
            self._holding = holding
            self.holding_pub.publish(Bool(holding))

    def _feedback(self, state) -> FollowJointTrajectoryFeedback:
        msg = FollowJointTrajectoryFeedback(joint_names=list(self.arm.joint_names))
        msg.header.stamp = conv.to_time(state.time_s)
        msg.desired = JointTrajectoryPoint(positions=state.desired_rad.tolist(),
                                           velocities=state.desired_rad_s.tolist(),
                                           accelerations=state.desired_rad_s2.tolist())
        msg.actual = JointTrajectoryPoint(positions=state.actual_rad.tolist(), velocities=state.actual_rad_s.tolist())
        msg.error = JointTrajectoryPoint(positions=(state.desired_rad - state.actual_rad).tolist(),
                                         velocities=(state.desired_rad_s - state.actual_rad_s).tolist())
        return msg
