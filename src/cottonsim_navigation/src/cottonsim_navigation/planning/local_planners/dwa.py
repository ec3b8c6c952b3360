"""A Dynamic Window Approach local planner (dwa_local_planner equivalent).

One control cycle (``compute_velocity``):

1. Prune the global plan up to the point nearest the robot; the local plan is
   what follows, up to where it leaves the local costmap; its last point is
   the local goal.
2. Goal logic (base_local_planner's LatchedStopRotateController): inside
   xy_goal_tolerance of the final goal, stop, then rotate in place to the
   goal yaw; ``latch_xy_goal_tolerance`` keeps the position counted as
   reached once it was. The turn rate is the fastest from which the robot can
   still stop on the goal yaw after holding it for one control period (ROS
   brakes as if the next command came at once, and overshoots at 5 Hz).
3. Dynamic window: velocities reachable within one control period
   (1 / controller_frequency) from the current (v, w) under acc_lim_x /
   acc_lim_theta, clipped to [min_vel_x, max_vel_x] and
   [-max_rot_vel, max_rot_vel]; sampled on a vx_samples x vth_samples grid.
   Samples that would barely move (|v| < min_vel_trans and |w| < min_rot_vel)
   are dropped, as the trajectory generator does.
4. Every sample is forward-simulated for sim_time (constant velocity, exact
   unicycle arcs; step count from sim_granularity / angular_sim_granularity)
   -- all samples at once with numpy; the footprint scan along them is a
   small compiled (numba) loop.
5. Scores, as DWAPlanner combines them (distances in metres; ROS computes
   cells x resolution, which is the same): path_distance_bias x (distance of
   the end point to the local plan + of the point forward_point_distance ahead
   of it, the "alignment" term, dropped near the goal) + goal_distance_bias x
   (distance of the end point to the local goal + of the forward point to a
   point forward_point_distance beyond the local goal, seen from the robot) +
   occdist_scale x (highest footprint cost along the trajectory). Distance
   fields are Euclidean distance transforms over the local costmap grid (ROS
   propagates a grid wavefront around obstacles instead; trajectories into
   obstacles are rejected anyway); with ``exact_distances`` the exact
   distances to the local plan's polyline and to the local goal instead.
   A trajectory is rejected when any pose has a LETHAL or NO_INFORMATION
   cell under its footprint outline, an INSCRIBED-or-worse cell under its
   centre (base_local_planner's CostmapModel rules), or leaves the costmap.
   Lowest score wins.
6. Oscillation suppression: while turning almost in place, the turning
   direction is kept until the robot has moved oscillation_reset_dist or
   turned oscillation_reset_angle (a simplified OscillationCostFunction).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Optional, Tuple

import numpy as np

from cottonsim_common.angles import shortest_angular_distance
from cottonsim_common.pose import Pose2D, as_pose
from cottonsim_common.validation import require_fields
from cottonsim_navigation.planning.base import LocalPlanner, LocalPlannerStatus, register_local_planner
from cottonsim_navigation.planning.local_planners.trajectories import (distance_fields, footprint_collides,
                                                                     polyline_distance, simulate_arcs)


@dataclass(frozen=True)
class DWAConfig:
    """dwa_local_planner parameters (names as the ROS ones).

    Velocities in m/s and rad/s, accelerations in m/s^2 and rad/s^2,
    tolerances in m and rad, times in s. Defaults: the original's values for
    max_vel_x 0.5, min_vel_x 0, max_rot_vel 1.0, min_rot_vel 0.2,
    acc_lim_x 2.5, acc_lim_theta 3.2, xy_goal_tolerance 0.2,
    yaw_goal_tolerance 0.1, controller_frequency 5; dwa_local_planner's
    defaults for the rest (sim_time 1.7, sim_granularity 0.025,
    angular_sim_granularity 0.1, vth_samples 20,
    path_distance_bias 32, goal_distance_bias 24, occdist_scale 0.01,
    forward_point_distance 0.325, oscillation_reset_dist 0.05,
    oscillation_reset_angle 0.2, trans/theta_stopped_vel 0.1).
    exact_distances: False (default) = distances to the local plan and goal
    from Euclidean distance transforms of the costmap grid, as ROS (cells x
    resolution); True = exact point-to-polyline / point-to-point distances.
    On the 0.05 m grid a lateral error under about one cell scores the same as
    none, so the grid version never corrects a robot 2-4 cm beside its path
    (port's addition for the GPS experiment's in-row accuracy).
    vx_samples: 6, NOT dwa's default 3: with 3 samples over [0, 0.5] the
    slowest forward sample is 0.25 m/s, which over sim_time 1.7 s runs
    0.43 m, more than twice xy_goal_tolerance, and the planner then stalls
    turning in place ~0.25 m short of the goal (seen in the unit test).
    """

    max_vel_x: float = 0.5
    min_vel_x: float = 0.0
    min_vel_trans: float = 0.1
    max_rot_vel: float = 1.0
    min_rot_vel: float = 0.2
    acc_lim_x: float = 2.5
    acc_lim_theta: float = 3.2
    xy_goal_tolerance: float = 0.2
    yaw_goal_tolerance: float = 0.1
    latch_xy_goal_tolerance: bool = False
    exact_distances: bool = False
    controller_frequency: float = 5.0
    sim_time: float = 1.7
    sim_granularity: float = 0.025
    angular_sim_granularity: float = 0.1
    vx_samples: int = 6
    vth_samples: int = 20
    path_distance_bias: float = 32.0
    goal_distance_bias: float = 24.0
    occdist_scale: float = 0.01
    forward_point_distance: float = 0.325
    oscillation_reset_dist: float = 0.05
    oscillation_reset_angle: float = 0.2
    trans_stopped_vel: float = 0.1
    theta_stopped_vel: float = 0.1

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.type in ("bool", bool):
                if not isinstance(v, bool):
                    raise ValueError(f"{f.name} must be true or false, got {v!r}")
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{f.name} must be a finite number, got {v!r}")
        require_fields(self, positive=("max_vel_x", "max_rot_vel", "acc_lim_x", "acc_lim_theta", "controller_frequency",
                                       "sim_time", "sim_granularity", "angular_sim_granularity"),
                       non_negative=("min_rot_vel", "min_vel_trans", "xy_goal_tolerance", "yaw_goal_tolerance",
                                     "path_distance_bias", "goal_distance_bias", "occdist_scale",
                                     "forward_point_distance", "oscillation_reset_dist", "oscillation_reset_angle",
                                     "trans_stopped_vel", "theta_stopped_vel"))
        if self.min_vel_x > self.max_vel_x:
            raise ValueError(f"min_vel_x ({self.min_vel_x}) exceeds max_vel_x ({self.max_vel_x})")
        if self.min_rot_vel > self.max_rot_vel:
            raise ValueError(f"min_rot_vel ({self.min_rot_vel}) exceeds max_rot_vel ({self.max_rot_vel})")
        for name in ("vx_samples", "vth_samples"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")


class DWAPlanner(LocalPlanner):
    """dwa_local_planner/DWAPlannerROS equivalent; see the module docstring.

    The plan given to ``set_plan`` and the poses given to the other methods
    must be in the local costmap's frame (the ROS layer transforms them).
    ``costmap`` is a Costmap2D (anything with ``.spec``, ``.costs`` and
    ``.footprint`` works).
    """

    def __init__(self, config: DWAConfig = DWAConfig()):
        self.config = config
        self.plan = np.zeros((0, 3))
        self._progress = 0
        self._xy_latched = False
        self._osc_sign = 0
        self._osc_ref: Optional[Tuple[float, float, float]] = None
        self.last_scores: Optional[np.ndarray] = None      # for debugging / visualisation
        self.last_samples: Optional[np.ndarray] = None

    # --- plan --------------------------------------------------------------
    @staticmethod
    def _as_plan_array(path) -> np.ndarray:
        if hasattr(path, "poses") and not isinstance(path, np.ndarray):
            path = path.poses
        if isinstance(path, (list, tuple)) and path and hasattr(path[0], "x_m"):
            path = [(p.x_m, p.y_m, getattr(p, "yaw_rad", 0.0)) for p in path]
        arr = np.asarray(path, dtype=float)
        if arr.size == 0:
            arr = np.zeros((0, 3))
        if arr.ndim != 2 or arr.shape[1] not in (2, 3):
            raise ValueError(f"plan must be a (K, 2) or (K, 3) array of poses, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError("plan contains non-finite coordinates")
        if arr.shape[1] == 2:
            yaw = np.zeros(len(arr))
            if len(arr) > 1:
                d = np.diff(arr, axis=0)
                yaw[:-1] = np.arctan2(d[:, 1], d[:, 0])
                yaw[-1] = yaw[-2]
            arr = np.column_stack([arr, yaw])
        return arr

    def set_plan(self, path) -> None:
        """A new global plan: progress, the goal latch and the oscillation flags start afresh."""
        self.plan = self._as_plan_array(path)
        self._progress = 0
        self._xy_latched = False
        self._osc_sign = 0
        self._osc_ref = None

    def update_plan_frame(self, path) -> None:
        """The same plan after a localisation correction moved it in the local frame.

        Keeps the progress along the plan and the xy-goal latch (a latched robot
        turning in place at its goal would otherwise lose the latch at every GPS
        update, drop back to driving mode and dither around the goal). A path of
        another length is a new plan (set_plan).
        """
        arr = self._as_plan_array(path)
        if len(arr) != len(self.plan):
            self.set_plan(arr)
            return
        self.plan = arr

    @property
    def goal(self) -> Optional[np.ndarray]:
        return self.plan[-1] if len(self.plan) else None

    # --- goal checks -----------------------------------------------------------
    def _xy_reached(self, pose: Pose2D) -> bool:
        g = self.goal
        if g is None:
            return False
        if self._xy_latched:
            return True
        reached = math.hypot(pose.x_m - g[0], pose.y_m - g[1]) <= self.config.xy_goal_tolerance
        if reached and self.config.latch_xy_goal_tolerance:
            self._xy_latched = True
        return reached

    def is_goal_reached(self, pose, velocity) -> bool:
        pose = as_pose(pose)
        v, w = (float(velocity[0]), float(velocity[1]))
        g = self.goal
        if g is None:
            return False
        if not self._xy_reached(pose):
            return False
        if abs(shortest_angular_distance(pose.yaw_rad, g[2])) > self.config.yaw_goal_tolerance:
            return False
        return abs(v) <= self.config.trans_stopped_vel and abs(w) <= self.config.theta_stopped_vel

    # --- helpers -----------------------------------------------------------------
    def _local_plan(self, pose: Pose2D, spec) -> np.ndarray:
        """Plan from the point nearest the robot (never going backwards) while inside the map."""
        # nearest of the next points (a bounded look-ahead, so a path that later
        # passes near the robot again is not cut short); progress never goes back
        ahead = self.plan[self._progress:self._progress + 400]
        d = np.hypot(ahead[:, 0] - pose.x_m, ahead[:, 1] - pose.y_m)
        self._progress += int(np.argmin(d))
        rest = self.plan[self._progress:]
        inside = spec.contains_world(rest[:, 0], rest[:, 1])
        if not inside[0]:
            return rest[:0]
        leave = np.flatnonzero(~inside)
        return rest[: leave[0]] if leave.size else rest

    def _update_oscillation(self, pose: Pose2D) -> None:
        if self._osc_ref is None:
            return
        x, y, th = self._osc_ref
        if (math.hypot(pose.x_m - x, pose.y_m - y) >= self.config.oscillation_reset_dist
                or abs(shortest_angular_distance(th, pose.yaw_rad)) >= self.config.oscillation_reset_angle):
            self._osc_sign = 0
            self._osc_ref = None

    def _rotate_to_goal(self, pose, v, w, costmap) -> Tuple[float, float, LocalPlannerStatus]:
        """LatchedStopRotateController: brake, then turn in place towards the goal yaw."""
        c = self.config
        dt = 1.0 / c.controller_frequency
        if abs(v) > c.trans_stopped_vel:
            # slow down first (stopWithAccLimits)
            nv = math.copysign(max(0.0, abs(v) - c.acc_lim_x * dt), v)
            nw = math.copysign(max(0.0, abs(w) - c.acc_lim_theta * dt), w)
            return nv, nw, LocalPlannerStatus.ROTATING_TO_GOAL
        err = shortest_angular_distance(pose.yaw_rad, float(self.goal[2]))
        # fastest speed from which we can still stop at the goal yaw, counting that the command is
        # held for a whole control period before the next one can brake: w dt + w^2 / (2 a) = |err|.
        # (ROS's sqrt(2 a |err|) assumes braking starts at once; at 5 Hz it overshoots by up to
        # w dt = 0.2 rad, beyond yaw_goal_tolerance, and the robot swings back and forth.)
        a_dt = c.acc_lim_theta * dt
        w_stop = -a_dt + math.sqrt(a_dt * a_dt + 2.0 * c.acc_lim_theta * abs(err))
        w_cmd = min(c.max_rot_vel, w_stop, abs(w) + c.acc_lim_theta * dt)
        w_cmd = max(c.min_rot_vel, w_cmd)
        w_cmd = math.copysign(w_cmd, err)
        turned = Pose2D(pose.x_m, pose.y_m, pose.yaw_rad + w_cmd * dt)
        if footprint_collides(costmap, np.array([[turned.x_m]]), np.array([[turned.y_m]]),
                               np.array([[turned.yaw_rad]]))[0]:
            return 0.0, 0.0, LocalPlannerStatus.NO_VALID_TRAJECTORY
        return 0.0, w_cmd, LocalPlannerStatus.ROTATING_TO_GOAL

    # --- main -------------------------------------------------------------------------
    def compute_velocity(self, pose, velocity, costmap) -> Tuple[float, float, LocalPlannerStatus]:
        c = self.config
        pose = as_pose(pose)
        try:
            v0, w0 = float(velocity[0]), float(velocity[1])
        except (TypeError, IndexError, ValueError):
            raise ValueError(f"velocity must be (v m/s, w rad/s), got {velocity!r}") from None
        if not (math.isfinite(v0) and math.isfinite(w0)):
            raise ValueError(f"velocity must be finite, got {velocity!r}")
        if len(self.plan) == 0:
            return 0.0, 0.0, LocalPlannerStatus.NO_PLAN
        spec = costmap.spec
        if not bool(spec.contains_world(pose.x_m, pose.y_m)):
            return 0.0, 0.0, LocalPlannerStatus.OFF_MAP

        if self._xy_reached(pose):
            if self.is_goal_reached(pose, (v0, w0)):
                return 0.0, 0.0, LocalPlannerStatus.GOAL_REACHED
            if abs(shortest_angular_distance(pose.yaw_rad, float(self.goal[2]))) <= c.yaw_goal_tolerance:
                # aligned: just brake to a stop
                dt = 1.0 / c.controller_frequency
                nv = math.copysign(max(0.0, abs(v0) - c.acc_lim_x * dt), v0)
                nw = math.copysign(max(0.0, abs(w0) - c.acc_lim_theta * dt), w0)
                return nv, nw, LocalPlannerStatus.ROTATING_TO_GOAL
            return self._rotate_to_goal(pose, v0, w0, costmap)

        local = self._local_plan(pose, spec)
        if len(local) == 0:
            return 0.0, 0.0, LocalPlannerStatus.NO_PLAN
        self._update_oscillation(pose)

        # 3. dynamic window and samples
        dt = 1.0 / c.controller_frequency
        vlo = max(c.min_vel_x, v0 - c.acc_lim_x * dt)
        vhi = min(c.max_vel_x, v0 + c.acc_lim_x * dt)
        wlo = max(-c.max_rot_vel, w0 - c.acc_lim_theta * dt)
        whi = min(c.max_rot_vel, w0 + c.acc_lim_theta * dt)
        if vlo > vhi:
            vlo = vhi = min(max(v0, c.min_vel_x), c.max_vel_x)
        if wlo > whi:
            wlo = whi = min(max(w0, -c.max_rot_vel), c.max_rot_vel)
        vs = np.linspace(vlo, vhi, int(c.vx_samples)) if c.vx_samples > 1 else np.array([vhi])
        ws = np.linspace(wlo, whi, int(c.vth_samples)) if c.vth_samples > 1 else np.array([0.5 * (wlo + whi)])
        if wlo <= 0.0 <= whi:
            ws = np.unique(np.concatenate([ws, [0.0]]))   # always try driving straight
        V, W = np.meshgrid(vs, ws, indexing="ij")
        V = V.ravel()
        W = W.ravel()
        keep = ~((np.abs(V) < c.min_vel_trans) & (np.abs(W) < c.min_rot_vel))
        if self._osc_sign != 0:
            keep &= ~((np.abs(V) < c.min_vel_trans) & (np.sign(W) == -self._osc_sign))
        V, W = V[keep], W[keep]
        if V.size == 0:
            return 0.0, 0.0, LocalPlannerStatus.NO_VALID_TRAJECTORY

        # 4. forward simulation
        n_steps = max(1, int(math.ceil(max(c.sim_time * np.max(np.abs(V)) / c.sim_granularity,
                                           c.sim_time * np.max(np.abs(W)) / c.angular_sim_granularity))))
        t = np.linspace(c.sim_time / n_steps, c.sim_time, n_steps)
        xs, ys, ths = simulate_arcs(pose.x_m, pose.y_m, pose.yaw_rad, V, W, t)

        # 5. scores
        collide, occ = footprint_collides(costmap, xs, ys, ths, return_cost=True)
        ex, ey, eth = xs[:, -1], ys[:, -1], ths[:, -1]
        fx = ex + c.forward_point_distance * np.cos(eth)
        fy = ey + c.forward_point_distance * np.sin(eth)
        if c.exact_distances:
            def path_distance(qx, qy):
                return polyline_distance(qx, qy, local[:, :2])
            goal_cost = np.hypot(ex - local[-1, 0], ey - local[-1, 1])
        else:
            path_d, goal_d = distance_fields(spec, local)

            def lookup(field, qx, qy):
                mx, my = spec.world_to_map(qx, qy)
                inside = spec.in_bounds(mx, my)
                out = np.full(qx.shape, np.inf)
                out[inside] = field[my[inside], mx[inside]]
                return out

            def path_distance(qx, qy):
                return lookup(path_d, qx, qy)
            goal_cost = lookup(goal_d, ex, ey)
        path_cost = path_distance(ex, ey)
        # the nose is drawn to a point forward_point_distance beyond the local goal
        # (seen from the robot), as DWAPlanner shifts the plan's last pose
        lg = local[-1]
        a = math.atan2(lg[1] - pose.y_m, lg[0] - pose.x_m)
        front_goal_cost = np.hypot(fx - (lg[0] + c.forward_point_distance * math.cos(a)),
                                   fy - (lg[1] + c.forward_point_distance * math.sin(a)))
        g = self.goal
        near_goal = math.hypot(pose.x_m - g[0], pose.y_m - g[1]) <= c.forward_point_distance
        align_cost = np.zeros_like(path_cost) if near_goal else path_distance(fx, fy)
        score = (c.path_distance_bias * (path_cost + align_cost)
                 + c.goal_distance_bias * (goal_cost + front_goal_cost)
                 + c.occdist_scale * occ)
        score = np.where(collide | ~np.isfinite(score), np.inf, score)
        self.last_samples = np.column_stack([V, W])
        self.last_scores = score
        best = int(np.argmin(score))
        if not np.isfinite(score[best]):
            return 0.0, 0.0, LocalPlannerStatus.NO_VALID_TRAJECTORY
        bv, bw = float(V[best]), float(W[best])

        # 6. oscillation flags
        if abs(bv) < c.min_vel_trans and bw != 0.0:
            if self._osc_sign == 0:
                self._osc_sign = int(np.sign(bw))
                self._osc_ref = (pose.x_m, pose.y_m, pose.yaw_rad)
        return bv, bw, LocalPlannerStatus.OK


register_local_planner(["dwa_local_planner/DWAPlannerROS", "dwa", "DWAPlannerROS"],
                       lambda config=DWAConfig(): DWAPlanner(config))
