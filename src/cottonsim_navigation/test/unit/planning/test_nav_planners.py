"""navfn and DWA against independent expectations."""
import heapq
import math

import numpy as np
import pytest

from cottonsim_common.pose import Pose2D
from cottonsim_navigation.core.grid import GridSpec, LETHAL_OBSTACLE, INSCRIBED_INFLATED_OBSTACLE
from cottonsim_navigation.planning.base import (LocalPlannerStatus, make_global_planner, make_local_planner)
from cottonsim_navigation.planning.costmap import (Costmap2D, CostmapConfig, make_local_costmap)
from cottonsim_navigation.planning.global_planners.navfn import NavfnConfig, NavfnPlanner
from cottonsim_navigation.planning.local_planners.dwa import DWAConfig, DWAPlanner


class Grid:
    def __init__(self, costs, res=0.1):
        self.costs = np.asarray(costs, dtype=np.uint8)
        self.spec = GridSpec(res, self.costs.shape[1], self.costs.shape[0], 0.0, 0.0)


def brute_dijkstra(costs, start, goal):
    """Plain heapq Dijkstra with navfn's cell costs, same 8-connectivity rules."""
    h, w = costs.shape
    cc = 50.0 + 0.8 * costs.astype(float)
    cc[costs >= 253] = np.inf
    cc[costs == 255] = 253.0
    dist = {start: 0.0}
    pq = [(0.0, start)]
    while pq:
        d, (x, y) = heapq.heappop(pq)
        if (x, y) == goal:
            return d
        if d > dist[(x, y)]:
            continue
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                if dx == dy == 0:
                    continue
                nx, ny = x + dx, y + dy
                if not (0 <= nx < w and 0 <= ny < h) or not np.isfinite(cc[ny, nx]):
                    continue
                if dx and dy and (not np.isfinite(cc[y, nx]) or not np.isfinite(cc[ny, x])):
                    continue
                nd = d + cc[ny, nx] * (math.sqrt(2) if dx and dy else 1.0)
                if nd < dist.get((nx, ny), np.inf):
                    dist[(nx, ny)] = nd
                    heapq.heappush(pq, (nd, (nx, ny)))
    return np.inf


def centre(i):
    return 0.1 * i + 0.05


def test_straight_line_plan():
    g = Grid(np.zeros((10, 30)))
    plan = NavfnPlanner().make_plan(g, Pose2D(centre(2), centre(5), 0), Pose2D(centre(25), centre(5), 1.0))
    assert plan.ok
    assert np.allclose(plan.poses[:, 1], centre(5))
    assert plan.cost == pytest.approx(23 * 50.0)
    assert plan.length_m() == pytest.approx(2.3)
    assert plan.poses[-1, 2] == pytest.approx(1.0)          # goal yaw at the end
    assert np.allclose(plan.poses[1:-1, 2], 0.0)            # direction of travel


@pytest.mark.parametrize("use_astar", [True, False])
def test_detour_and_optimal_cost_vs_bruteforce(use_astar):
    rng = np.random.default_rng(3)
    costs = rng.integers(0, 200, size=(25, 30)).astype(np.uint8)
    costs[3:22, 15] = LETHAL_OBSTACLE            # wall with gaps at both ends
    costs[rng.random(costs.shape) < 0.1] = LETHAL_OBSTACLE
    costs[12, 2] = 0
    costs[12, 27] = 0
    g = Grid(costs)
    planner = NavfnPlanner(NavfnConfig(use_astar=use_astar))
    plan = planner.make_plan(g, Pose2D(centre(2), centre(12)), Pose2D(centre(27), centre(12)))
    expected = brute_dijkstra(costs, (2, 12), (27, 12))
    assert plan.ok and np.isfinite(expected)
    assert plan.cost == pytest.approx(expected, rel=1e-9)
    mx, my = g.spec.world_to_map(plan.poses[:, 0], plan.poses[:, 1])
    assert np.all(costs[my, mx] < INSCRIBED_INFLATED_OBSTACLE)      # never through lethal cells
    steps = np.abs(np.diff(np.column_stack([mx, my]), axis=0))
    assert steps.max() <= 1                                         # 8-connected chain
    # sum of the entered cells' costs along the path equals the planner's cost
    cc = 50.0 + 0.8 * costs[my, mx].astype(float)
    lens = np.where(steps.sum(axis=1) == 2, math.sqrt(2), 1.0)
    assert np.sum(cc[1:] * lens) == pytest.approx(expected)


def test_no_path_when_walled_in_and_tolerance_search():
    costs = np.zeros((20, 20), np.uint8)
    costs[:, 10] = LETHAL_OBSTACLE
    g = Grid(costs)
    p = NavfnPlanner()
    plan = p.make_plan(g, Pose2D(centre(2), centre(5)), Pose2D(centre(15), centre(5)), tolerance_m=0.3)
    assert not plan.ok and "no reachable cell" in plan.reason
    # goal on a lethal cell: the nearest free cell within the tolerance is used
    costs2 = np.zeros((20, 20), np.uint8)
    costs2[8:13, 8:13] = LETHAL_OBSTACLE
    g2 = Grid(costs2)
    plan = p.make_plan(g2, Pose2D(centre(2), centre(10)), Pose2D(centre(10), centre(10)), tolerance_m=0.35)
    assert plan.ok
    end = plan.poses[-1]
    assert math.hypot(end[0] - centre(10), end[1] - centre(10)) == pytest.approx(0.3)
    assert not p.make_plan(g2, Pose2D(centre(2), centre(10)), Pose2D(centre(10), centre(10)), 0.1).ok
    assert not p.make_plan(g2, Pose2D(-5, 0), Pose2D(centre(10), centre(10))).ok   # start off map


def test_start_in_an_obstacle_is_left_and_the_costmap_is_not_touched():
    # navfn clears the robot's own cell: a robot whose cell became lethal can still leave it
    costs = np.zeros((12, 20), np.uint8)
    costs[6, 3] = LETHAL_OBSTACLE
    before = costs.copy()
    g = Grid(costs)
    plan = NavfnPlanner().make_plan(g, Pose2D(centre(3), centre(6)), Pose2D(centre(15), centre(6)))
    assert plan.ok
    assert plan.cost == pytest.approx(brute_dijkstra(np.where(costs == LETHAL_OBSTACLE, 0, costs).astype(np.uint8),
                                                     (3, 6), (15, 6)))
    assert np.array_equal(g.costs, before)
    # the goal on the robot's own (lethal) cell: a zero-length plan, not a failure
    assert NavfnPlanner().make_plan(g, Pose2D(centre(3), centre(6)), Pose2D(centre(3), centre(6))).ok


def test_unknown_space_respects_allow_unknown():
    costs = np.zeros((10, 20), np.uint8)
    costs[:, 10] = 255
    g = Grid(costs)
    s, t = Pose2D(centre(2), centre(5)), Pose2D(centre(17), centre(5))
    assert NavfnPlanner(NavfnConfig(allow_unknown=True)).make_plan(g, s, t).ok
    assert not NavfnPlanner(NavfnConfig(allow_unknown=False)).make_plan(g, s, t).ok


def test_registry():
    assert isinstance(make_global_planner("navfn/NavfnROS"), NavfnPlanner)
    assert isinstance(make_local_planner("dwa_local_planner/DWAPlannerROS"), DWAPlanner)
    assert isinstance(make_local_planner("dwa", DWAConfig(max_vel_x=0.3)), DWAPlanner)
    with pytest.raises(ValueError, match="navfn"):
        make_global_planner("carrot_planner/CarrotPlanner")
    with pytest.raises(ValueError, match="max_vel_x"):
        DWAConfig(max_vel_x=-1.0)
    with pytest.raises(ValueError, match="vth_samples"):
        DWAConfig(vth_samples=0)


def _run(planner, costmap_factory, pose, plan, steps=200, dt=0.2):
    planner.set_plan(plan)
    v = w = 0.0
    poses = [pose]
    statuses = []
    for _ in range(steps):
        cm = costmap_factory(pose)
        v, w, st = planner.compute_velocity(pose, (v, w), cm)
        statuses.append(st)
        if st is LocalPlannerStatus.GOAL_REACHED:
            break
        # exact unicycle integration
        if abs(w) < 1e-9:
            pose = Pose2D(pose.x_m + v * dt * math.cos(pose.yaw_rad), pose.y_m + v * dt * math.sin(pose.yaw_rad),
                          pose.yaw_rad)
        else:
            th = pose.yaw_rad + w * dt
            pose = Pose2D(pose.x_m + v / w * (math.sin(th) - math.sin(pose.yaw_rad)),
                          pose.y_m - v / w * (math.cos(th) - math.cos(pose.yaw_rad)), th)
        poses.append(pose)
    return poses, statuses, v, w


def test_dwa_reaches_goal_in_free_space():
    cfg = CostmapConfig(global_frame="odom", rolling_window=True, width=5.0, height=5.0)
    cm = Costmap2D(cfg, [])

    def factory(pose):
        cm.update_map(pose)
        return cm
    plan = np.column_stack([np.linspace(0, 3, 61), np.linspace(0, 1, 61), np.full(61, math.pi / 2)])
    planner = DWAPlanner()
    poses, statuses, v, w = _run(planner, factory, Pose2D(0, 0, 0), plan)
    assert statuses[-1] is LocalPlannerStatus.GOAL_REACHED
    end = poses[-1]
    assert math.hypot(end.x_m - 3, end.y_m - 1) <= planner.config.xy_goal_tolerance
    assert abs(math.remainder(end.yaw_rad - math.pi / 2, 2 * math.pi)) <= planner.config.yaw_goal_tolerance
    assert planner.is_goal_reached(end, (0.0, 0.0))
    assert not planner.is_goal_reached(Pose2D(3, 1, 0.0), (0.0, 0.0))           # yaw off
    assert not planner.is_goal_reached(Pose2D(3, 1, math.pi / 2), (0.4, 0.0))   # still moving


def test_dwa_never_enters_lethal_cells():
    # a block of obstacle in front of the robot; the plan detours around it
    wall = np.array([[1.2, y, 0.3] for y in np.linspace(-0.6, 0.4, 40)])

    def factory(pose):
        cm = make_local_costmap()
        cm.obstacle_layer.add_observation(wall, (pose.x_m, pose.y_m, 0.5))
        cm.update_map(pose)
        return cm
    xs = np.concatenate([np.linspace(0, 0.6, 13), np.full(15, 0.6), np.linspace(0.6, 2.0, 29)])
    ys = np.concatenate([np.zeros(13), np.linspace(0, 1.1, 15), np.full(29, 1.1)])
    plan = np.column_stack([xs, ys])
    planner = DWAPlanner()
    poses, statuses, _, _ = _run(planner, factory, Pose2D(0, 0, 0), plan, steps=150)
    for p in poses:
        cm = factory(p)
        assert cm.footprint_cost(p) < LETHAL_OBSTACLE
    # and every sample it scored as finite in the last cycle is collision-free
    assert statuses.count(LocalPlannerStatus.NO_VALID_TRAJECTORY) == 0


def test_dwa_reports_no_valid_trajectory_when_boxed_in():
    # lethal everywhere except a box just larger than the footprint: no motion fits
    cm = Costmap2D(CostmapConfig(rolling_window=True, width=5.0, height=5.0), [])
    cm.update_map(Pose2D(0, 0, 0))
    cx, cy = cm.spec.map_to_world(*np.meshgrid(np.arange(100), np.arange(100)))
    free = (np.abs(cx) < 0.55) & (np.abs(cy) < 0.39)
    cm.costs[...] = LETHAL_OBSTACLE
    cm.costs[free] = 0
    assert cm.footprint_cost(Pose2D(0, 0, 0)) == 0
    planner = DWAPlanner()
    planner.set_plan(np.column_stack([np.linspace(0, 2, 41), np.zeros(41)]))
    v, w, st = planner.compute_velocity(Pose2D(0, 0, 0), (0.0, 0.0), cm)
    assert st is LocalPlannerStatus.NO_VALID_TRAJECTORY and v == 0.0 and w == 0.0
    assert np.all(~np.isfinite(planner.last_scores))


def test_dwa_keeps_its_goal_latch_when_only_the_plan_frame_moves():
    # robot inside xy_goal_tolerance, heading 90 deg off the goal yaw: latched, it turns in place
    cm = make_local_costmap()
    cm.update_map(Pose2D(0.0, 0.0, 0.0))
    dwa = DWAPlanner(DWAConfig(xy_goal_tolerance=0.08, latch_xy_goal_tolerance=True))
    path = np.column_stack([np.linspace(-1.0, 0.0, 21), np.zeros(21), np.zeros(21)])
    dwa.set_plan(path)
    robot = Pose2D(0.03, 0.0, math.pi / 2)
    v, w, st = dwa.compute_velocity(robot, (0.0, 0.0), cm)
    assert st is LocalPlannerStatus.ROTATING_TO_GOAL and v == 0.0 and w < 0.0
    # a localisation correction moves the same plan 0.15 m: still latched, still turning in place
    moved = path + np.array([0.15, 0.0, 0.0])
    dwa.update_plan_frame(moved)
    v, w, st = dwa.compute_velocity(robot, (0.0, w), cm)
    assert st is LocalPlannerStatus.ROTATING_TO_GOAL and v == 0.0
    # the same poses as a NEW plan: the latch is gone, the goal is 0.12 m away -> not rotating to it
    dwa.set_plan(moved)
    v, w, st = dwa.compute_velocity(robot, (0.0, 0.0), cm)
    assert st is not LocalPlannerStatus.ROTATING_TO_GOAL
    with pytest.raises(ValueError, match="non-finite"):
        dwa.update_plan_frame(np.full((21, 3), np.nan))


def test_goal_approach_joins_the_goal_heading_line_and_follows_it():
    g = Grid(np.zeros((40, 240)), res=0.05)                 # 12 x 2 m, empty
    start, goal = Pose2D(0.5, 1.07, 0.0), Pose2D(11.0, 1.0, 0.0)   # 7 cm beside the line y = 1
    plain = NavfnPlanner().make_plan(g, start, goal)
    joined = NavfnPlanner(NavfnConfig(goal_approach_join_m=1.0)).make_plan(g, start, goal)
    assert plain.ok and joined.ok
    p = joined.poses
    assert np.allclose(p[0, :2], [0.5, 1.07]) and np.allclose(p[-1], [11.0, 1.0, 0.0])
    # from 1 m ahead of the robot on, the plan lies on the goal's heading line
    on = p[:, 0] >= 1.5 + 1e-9
    assert on.sum() > 100 and np.max(np.abs(p[on, 1] - 1.0)) < 1e-9
    assert np.max(np.hypot(*np.diff(p[:, :2], axis=0).T)) < 0.05 * 2.0      # no jumps (a diagonal cell step)
    # the plain plan drifts from the robot's line to the goal instead
    mid = np.argmin(np.abs(plain.poses[:, 0] - 3.0))
    assert abs(plain.poses[mid, 1] - 1.0) > 0.02


def test_goal_approach_only_where_it_applies():
    planner = NavfnPlanner(NavfnConfig(goal_approach_join_m=1.0))
    base = NavfnPlanner()
    g = Grid(np.zeros((40, 240)), res=0.05)
    start = Pose2D(0.5, 1.07, 0.0)
    # goal heading 90 deg off the direction to it (a lane end): the ordinary plan
    side = Pose2D(11.0, 1.0, math.pi / 2)
    assert np.allclose(planner.make_plan(g, start, side).poses[:-1], base.make_plan(g, start, side).poses[:-1])
    # robot closer than the join distance: the ordinary plan
    near = Pose2D(1.2, 1.0, 0.0)
    assert np.allclose(planner.make_plan(g, start, near).poses, base.make_plan(g, start, near).poses)
    # an obstacle on the line: the ordinary plan, which goes around it
    costs = np.zeros((40, 240), np.uint8)
    costs[18:23, 150] = LETHAL_OBSTACLE                      # x = 7.5 m, across y = 1
    gb = Grid(costs, res=0.05)
    p = planner.make_plan(gb, start, Pose2D(11.0, 1.0, 0.0))
    mx, my = gb.spec.world_to_map(p.poses[:, 0], p.poses[:, 1])
    assert p.ok and np.all(costs[my, mx] < INSCRIBED_INFLATED_OBSTACLE)
    with pytest.raises(ValueError, match="goal_approach_join_m"):
        NavfnConfig(goal_approach_join_m=-1.0)
    with pytest.raises(ValueError, match="goal_approach_max_angle_rad"):
        NavfnConfig(goal_approach_max_angle_rad=2.0)


@pytest.mark.parametrize("goal_yaw", [math.pi / 2, 1.0, 0.5])
def test_dwa_turns_onto_the_goal_yaw_without_swinging_past_it(goal_yaw):
    # a unicycle whose command takes effect half a control period late (as the simulated base
    # does, counting the odometry delay): the in-place turn at the goal must end inside
    # yaw_goal_tolerance without swinging beyond it and back
    cfg = DWAConfig(xy_goal_tolerance=0.08, latch_xy_goal_tolerance=True)
    cm = make_local_costmap()
    cm.update_map(Pose2D(0.0, 0.0, 0.0))
    dwa = DWAPlanner(cfg)
    dwa.set_plan(np.column_stack([np.linspace(-1.0, 0.0, 21), np.zeros(21), np.full(21, goal_yaw)]))
    yaw, w = 0.0, 0.0
    errors = []
    dt = 1.0 / cfg.controller_frequency
    for _ in range(60):
        v, w_cmd, st = dwa.compute_velocity(Pose2D(0.0, 0.0, yaw), (0.0, w), cm)
        if st is LocalPlannerStatus.GOAL_REACHED:
            break
        assert v == 0.0
        yaw += 0.5 * dt * w + 0.5 * dt * w_cmd
        w = w_cmd
        errors.append(goal_yaw - yaw)
    assert st is LocalPlannerStatus.GOAL_REACHED
    assert abs(errors[-1]) <= cfg.yaw_goal_tolerance
    assert min(errors) > -cfg.yaw_goal_tolerance           # never swung past the tolerance band
    # at most 1 rad/s plus a few braking periods (the start-braking-at-once rule took ~twice as long)
    assert len(errors) * dt <= goal_yaw / cfg.max_rot_vel + 1.0


def _gps_experiment_dwa_config():
    """DWAConfig of the GPS experiment: dwa.yaml overridden by gps_navigation_move_base.yaml."""
    import pathlib
    import yaml
    cfg_dir = pathlib.Path(__file__).resolve().parents[3] / "config"
    params = dict(yaml.safe_load((cfg_dir / "dwa.yaml").read_text())["DWAPlannerROS"])
    params.update(yaml.safe_load((cfg_dir / "gps_navigation_move_base.yaml").read_text())["DWAPlannerROS"])
    return DWAConfig(**params)


@pytest.mark.parametrize("short_m", [0.083, 0.12, 0.3])
def test_gps_experiment_dwa_settings_reach_a_goal_from_just_outside_the_tolerance(short_m):
    # a stopped robot on the line to the goal, short_m before it: the experiment's DWA must arrive
    # (latch) instead of dithering in place; an ideal unicycle follows each command for one period
    cfg = _gps_experiment_dwa_config()
    assert cfg.xy_goal_tolerance < short_m
    cm = make_local_costmap()
    cm.update_map(Pose2D(0.0, 0.0, 0.0))
    dwa = DWAPlanner(cfg)
    dwa.set_plan(np.column_stack([np.linspace(-1.0, 0.0, 41), np.zeros(41), np.zeros(41)]))
    x, yaw, v, w = -short_m, 0.0, 0.0, 0.0
    dt = 1.0 / cfg.controller_frequency
    for _ in range(50):
        v, w, st = dwa.compute_velocity(Pose2D(x, 0.0, yaw), (v, w), cm)
        if st is LocalPlannerStatus.GOAL_REACHED:
            break
        x += v * dt * math.cos(yaw)
        yaw += w * dt
    assert st is LocalPlannerStatus.GOAL_REACHED
    assert abs(x) <= cfg.xy_goal_tolerance


def _track_lane(cfg, offset_m, lane_y=0.012):
    """Mean |lateral error| [m] while an ideal unicycle (commands half a period late) follows a
    straight 12 m plan, starting offset_m beside it; measured over x = 3..10 m."""
    dwa = DWAPlanner(cfg)
    dwa.set_plan(np.column_stack([np.linspace(0, 12, 481), np.full(481, lane_y), np.zeros(481)]))
    x, y, yaw, v, w = 0.0, lane_y + offset_m, 0.0, 0.0, 0.0
    errors = []
    cm = make_local_costmap()
    for _ in range(120):
        cm.update_map(Pose2D(x, y, yaw))                   # rolling window, empty
        v_new, w_new, st = dwa.compute_velocity(Pose2D(x, y, yaw), (v, w), cm)
        if st is LocalPlannerStatus.GOAL_REACHED:
            break
        for k in range(10):
            vv, ww = (v, w) if k < 5 else (v_new, w_new)
            x += vv * 0.02 * math.cos(yaw)
            y += vv * 0.02 * math.sin(yaw)
            yaw += ww * 0.02
        v, w = v_new, w_new
        if 3.0 < x < 10.0:
            errors.append(abs(y - lane_y))
    assert len(errors) > 20
    return float(np.mean(errors))


def test_exact_distances_correct_small_lateral_errors_the_grid_cannot_see():
    # on the 0.05 m grid a robot 3 cm beside its plan scores (almost) like one on it and stays there;
    # with exact distances it comes back onto the plan
    base = dict(max_vel_x=0.7, min_vel_trans=0.05, vx_samples=11)
    grid = _track_lane(DWAConfig(**base), 0.03)
    exact = _track_lane(DWAConfig(exact_distances=True, **base), 0.03)
    assert grid > 0.025
    assert exact < 0.6 * grid and exact < 0.02
    with pytest.raises(ValueError, match="exact_distances"):
        DWAConfig(exact_distances=1)
