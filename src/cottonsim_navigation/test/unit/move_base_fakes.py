"""Fake planners, a counting recovery and empty costmaps for the move_base state machine's unit tests."""
import numpy as np

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.core.grid import GridSpec
from cottonsim_navigation.move_base.recovery import RecoveryBehaviour
from cottonsim_navigation.move_base.state_machine import Outcome
from cottonsim_navigation.planning.base import GlobalPlanner, LocalPlanner, LocalPlannerStatus, Plan
from cottonsim_navigation.planning.costmap import (Costmap2D, CostmapConfig, InflationLayer, ObstacleLayer,
                                                   StaticLayer, make_global_costmap, make_local_costmap)

DT = 0.2   # 1 / controller_frequency 5 Hz


class FakeGlobal(GlobalPlanner):
    """Straight two-pose plans, or failure while ``fail`` is set; records the goals asked for."""

    def __init__(self, fail=False):
        self.fail = fail
        self.goals = []

    def make_plan(self, costmap, start, goal, tolerance_m=None):
        self.goals.append(goal)
        if self.fail:
            return Plan.empty("fake: no path")
        return Plan(np.array([[start.x_m, start.y_m, 0.0], [goal.x_m, goal.y_m, goal.yaw_rad]]), "", 1.0)


class FakeLocal(LocalPlanner):
    """Returns the scripted (v, w, status); records the plans it was given."""

    def __init__(self, v=0.3, w=0.0, status=LocalPlannerStatus.OK):
        self.v, self.w, self.status = v, w, status
        self.plans = []
        self.calls = []          # "set_plan" / "update_plan_frame", in order

    def set_plan(self, path):
        self.plans.append(np.asarray(path, dtype=float))
        self.calls.append("set_plan")

    def update_plan_frame(self, path):
        self.plans.append(np.asarray(path, dtype=float))
        self.calls.append("update_plan_frame")

    def compute_velocity(self, pose, velocity, costmap):
        return self.v, self.w, self.status

    def is_goal_reached(self, pose, velocity):
        return self.status == LocalPlannerStatus.GOAL_REACHED


class CountingRecovery(RecoveryBehaviour):
    """Finishes after ``cycles`` steps; logs its name into a shared list when started."""

    def __init__(self, name, log, cycles=1):
        self.name, self.log, self.cycles = name, log, cycles

    def start(self, local_pose, costmaps):
        self.log.append(self.name)
        self.left = self.cycles

    def step(self, local_pose, velocity, local_costmap, dt_s):
        self.left -= 1
        return 0.0, 0.5, self.left <= 0


def empty_costmaps(obstacle_layer_in_global=False):
    spec = GridSpec(0.05, 200, 200, -5.0, -5.0)
    occ = np.zeros(spec.shape, np.int8)
    if obstacle_layer_in_global:
        glob = Costmap2D(CostmapConfig(track_unknown_space=True),
                         [StaticLayer(), ObstacleLayer(), InflationLayer()])
        glob.resize(spec)
        glob.static_layer.set_map(occ, spec)
        glob.update_map(Pose2D(0, 0, 0))
    else:
        glob = make_global_costmap(occ, spec)
    local = make_local_costmap()
    local.update_map(Pose2D(0, 0, 0))
    return glob, local


def run(mb, steps, t0=0.0, pose=Pose2D(0, 0, 0), move=None):
    """Step the machine; returns the results and the time after the last step."""
    out = []
    t = t0
    for _ in range(steps):
        if move is not None:
            pose = move(pose, t)
        r = mb.step(t, pose, pose, (0.0, 0.0))
        out.append(r)
        t += DT
        if r.outcome in (Outcome.SUCCEEDED, Outcome.ABORTED):
            break
    return out, t
