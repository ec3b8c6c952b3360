"""The arm as the harvest node drives it: its joints, its trajectory action, its vacuum.

Subscriptions
  /joint_states (sensor_msgs/JointState): the arm's joints (the names given, in that order).
Action client / service client
  /arm_controller/follow_joint_trajectory (cottonsim_msgs/FollowJointTrajectory), /arm_controller/vacuum
      (std_srvs/SetBool).

One trajectory is in flight at a time. Its end comes back as a pick-cycle event
(TrajectoryDone / TrajectoryFailed) from pop_events(); a cancelled or superseded
trajectory's end is dropped. A trajectory is sent at once when it starts where the
last one ended (the controller reported it done: the arm is there, at rest); else once
/joint_states shows the arm at rest (after a cancel it brakes first), from where it
stopped when that is off the trajectory's start (START_TOLERANCE_RAD). /joint_states
alone is not trusted right after a motion: on a loaded machine it can lag the
controller's report by a whole approach, and a lead-in from there is a jump.
"""
from __future__ import annotations

import collections
import threading
from typing import Callable, List, Optional, Sequence

import actionlib
import numpy as np
import rospy
from actionlib_msgs.msg import GoalStatus
from cottonsim_msgs.msg import FollowJointTrajectoryAction, FollowJointTrajectoryGoal
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool
from trajectory_msgs.msg import JointTrajectoryPoint

from cottonsim_manipulation.harvest.pick_cycle import TrajectoryDone, TrajectoryFailed
from cottonsim_manipulation.planning.trajectory import JointTrajectory, TrajectoryConfig, plan_trajectory

REST_SPEED_RAD_S = 0.01                         # the arm is at rest below this joint speed [rad/s]
START_TOLERANCE_RAD = 0.01                      # a trajectory starting farther from the arm gets a lead-in [rad]


class ArmClient:
    """The arm's ROS API for one user; on_event() is called (from a ROS thread) when a trajectory ends."""

    def __init__(self, joint_names: Sequence[str], trajectory_config: TrajectoryConfig,
                 on_event: Callable[[], None] = lambda: None):
        self.joint_names = list(joint_names)
        self.trajectory_config = trajectory_config
        self._on_event = on_event
        self._lock = threading.Lock()
        self._events = collections.deque()       # TrajectoryDone / TrajectoryFailed of the trajectory in flight
        self._q: Optional[np.ndarray] = None
        self._qd: Optional[np.ndarray] = None
        self._waiting: Optional[JointTrajectory] = None   # a trajectory to send once the arm is at rest
        self._seq = 0                            # the trajectory in flight (0: none)
        self._sent_end_rad = None                # the last point of the trajectory in flight (seq _seq)
        self._rest_at = None                     # where the last trajectory ended, succeeded, while nothing moved since
        self._goal = None                        # the goal handle of the trajectory in flight
        self.action = actionlib.ActionClient("/arm_controller/follow_joint_trajectory", FollowJointTrajectoryAction)
        self.vacuum_service = rospy.ServiceProxy("/arm_controller/vacuum", SetBool)
        rospy.Subscriber("/joint_states", JointState, self._on_joints, queue_size=5)

    # ------------------------------------------------------------------ state
    def wait_for_server(self, timeout_s: float) -> bool:
        return self.action.wait_for_server(rospy.Duration(timeout_s))

    def joints(self) -> Optional[np.ndarray]:
        """The arm's joint positions [rad] from the last /joint_states (None before the first)."""
        with self._lock:
            return self._q

    def pop_events(self) -> List[object]:
        """The ends of trajectories (TrajectoryDone / TrajectoryFailed) since the last call, in order."""
        with self._lock:
            events = list(self._events)
            self._events.clear()
        return events

    # ------------------------------------------------------------------ commands
    def send(self, trajectory: JointTrajectory) -> None:
        """Send the trajectory now or, when the arm must come to rest first, from send_waiting()."""
        self._waiting = trajectory
        self.send_waiting()

    def send_waiting(self) -> None:
        """Send the waiting trajectory if the arm is ready for it (call every loop cycle)."""
        trajectory = self._waiting
        with self._lock:
            q, qd, rest_at = self._q, self._qd, self._rest_at
        if trajectory is None:
            return
        continues = rest_at is not None and np.abs(rest_at - trajectory.waypoints_rad[0]).max() <= START_TOLERANCE_RAD
        if not continues:
            if q is None or (qd is not None and np.abs(qd).max() > REST_SPEED_RAD_S):
                return
            if np.abs(q - trajectory.waypoints_rad[0]).max() > START_TOLERANCE_RAD:
                trajectory = plan_trajectory(np.vstack([q, trajectory.waypoints_rad]), self.trajectory_config)
        self._waiting = None
        times, q, qd, qdd = trajectory.sampled()
        goal = FollowJointTrajectoryGoal()
        goal.trajectory.joint_names = list(self.joint_names)
        goal.trajectory.points = [JointTrajectoryPoint(positions=q[i].tolist(), velocities=qd[i].tolist(),
                                                       accelerations=qdd[i].tolist(),
                                                       time_from_start=rospy.Duration.from_sec(float(t)))
                                  for i, t in enumerate(times)]
        with self._lock:
            self._seq += 1
            seq = self._seq
            self._sent_end_rad = np.array(trajectory.waypoints_rad[-1], dtype=float)
            self._rest_at = None
        self._goal = self.action.send_goal(goal, transition_cb=lambda handle, s=seq: self._on_transition(s, handle))

    def cancel(self) -> None:
        """Stop the trajectory in flight (the controller brakes) and forget a waiting one."""
        with self._lock:
            self._seq = 0
            self._rest_at = None
        self._waiting = None
        if self._goal is not None:
            self._goal.cancel()
            self._goal = None

    def set_vacuum(self, on: bool) -> None:
        try:
            self.vacuum_service(on)
        except (rospy.ServiceException, rospy.ROSException) as exc:
            rospy.logwarn("harvest: vacuum %s failed: %s", "on" if on else "off", exc)

    # ------------------------------------------------------------------ callbacks (ROS threads)
    def _on_joints(self, msg: JointState) -> None:
        try:
            index = [msg.name.index(j) for j in self.joint_names]
            q = np.array([msg.position[i] for i in index])
            qd = np.array([msg.velocity[i] for i in index]) if len(msg.velocity) == len(msg.name) else None
        except (ValueError, IndexError):
            return
        with self._lock:
            self._q, self._qd = q, qd

    def _on_transition(self, seq: int, handle) -> None:
        """actionlib transition callback of the trajectory sent as number seq."""
        if handle.get_comm_state() != actionlib.CommState.DONE:
            return
        state, result = handle.get_goal_status(), handle.get_result()
        if state == GoalStatus.SUCCEEDED:
            event = TrajectoryDone()
        elif state in (GoalStatus.ABORTED, GoalStatus.REJECTED, GoalStatus.LOST):
            event = TrajectoryFailed(getattr(result, "error_string", "") or handle.get_goal_status_text())
        else:
            return                                   # cancelled or preempted by us
        with self._lock:
            if seq != self._seq:
                return
            self._events.append(event)
            if isinstance(event, TrajectoryDone):
                self._rest_at = self._sent_end_rad      # the controller holds the arm there, at rest
        self._on_event()
