"""A navfn-equivalent global planner (navfn/NavfnROS).

What it does, step by step:

1. Cell costs as navfn computes them from the costmap: a cell of costmap cost
   c < 253 costs ``neutral_cost + cost_factor * c`` (navfn: 50 + 0.8 c) to
   enter; INSCRIBED (253) and LETHAL (254) cells are impassable; unknown
   (255) cells cost 253 when ``allow_unknown`` and are impassable otherwise.
   The robot's own cell is always passable (navfn clears it).
2. A potential field by Dijkstra on the 8-connected grid: entering a
   neighbour costs its cell cost times the step length (1 or sqrt 2 cells).
   A diagonal step is only allowed when both cells it squeezes between are
   passable (no corner cutting). Like NavfnROS, which swaps start and goal,
   the field is propagated from the robot's cell; it stops as soon as the goal
   (or every candidate cell of the tolerance search) has its final value.
   Dijkstra runs in compiled code (numba, indexed binary heap, reading the
   1-byte costmap through a 256-entry cost table); by default
   the queue is ordered A*-style with a consistent heuristic (neutral cost x
   octile distance to the goal), which finds the same optimal potential along
   the path and lets a 40 x 40 m map plan in tens of milliseconds (the cells
   far from the path keep an infinite potential; ``use_astar=False`` gives
   the full field).
3. Goal tolerance: if the goal cell cannot be reached (lethal, or walled in),
   the reachable cell nearest the goal within ``tolerance_m`` (a square
   window, as NavfnROS searches) becomes the end of the path.
4. Path extraction: from the end cell, follow each cell's Dijkstra parent
   back to the start. This is the steepest descent of the exact 8-connected
   potential (navfn instead interpolates the gradient of its 4-connected,
   quadratically-updated field, which gives slightly smoother lines); the
   path is cost-optimal on the 8-connected graph.
5. Orientation filter: each pose looks along the path (direction from the
   pose ``orientation_window_m`` behind to the one that far ahead); the last
   pose takes the goal's yaw.

Port's addition, off by default (``goal_approach_join_m`` = 0): approach the
goal along its heading. A waypoint route's goal heading is the direction of
the leg it starts (goals face the next waypoint), so for a goal straight ahead
(the direction to it within ``goal_approach_max_angle_rad`` of its heading)
the line through the goal along its heading is the lane the robot is driving.
The plan then joins that line ``goal_approach_join_m`` ahead of the robot's
foot point on it (navfn from the robot to the join point) and follows it
straight to the goal; if any cell of that straight part is impassable
(INSCRIBED or worse), or the robot is closer than the join distance, the
ordinary plan is made instead. Why: a robot that stopped a few centimetres
beside a lane-entry waypoint otherwise drives the whole lane on the slanted
line from where it stopped to the next waypoint, beside the lane's centre.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

try:
    from numba import njit
except ImportError as exc:  # pragma: no cover
    raise ImportError("the navfn planner needs numba (pip install numba)") from exc

from cottonsim_common.angles import wrap_angle
from cottonsim_common.pose import Pose2D, as_pose
from cottonsim_common.validation import require_fields
from cottonsim_navigation.core.grid import INSCRIBED_INFLATED_OBSTACLE, NO_INFORMATION
from cottonsim_navigation.planning.base import GlobalPlanner, Plan, register_global_planner

SQRT2 = math.sqrt(2.0)


@dataclass(frozen=True)
class NavfnConfig:
    """navfn parameters (names as NavfnROS; navfn defaults unless noted).

    allow_unknown: plan through NO_INFORMATION cells (the original: true);
    default_tolerance [m]: goal tolerance used when make_plan gets None
    (the original: 0.1); neutral_cost / cost_factor: navfn's COST_NEUTRAL 50
    and COST_FACTOR 0.8; orientation_window_m [m]: half-window of the
    orientation filter; use_astar: order the search by potential + a
    consistent distance heuristic (same optimal path, far fewer cells
    expanded; False gives navfn's full Dijkstra wave).
    goal_approach_join_m [m]: > 0 = approach a goal ahead along its heading,
    joining that line this far ahead of the robot (see the module docstring);
    0 = off (navfn). goal_approach_max_angle_rad [rad]: how far the direction
    to the goal may differ from the goal's heading for that (default 0.35 = 20 deg).
    """

    allow_unknown: bool = True
    default_tolerance: float = 0.1
    neutral_cost: float = 50.0
    cost_factor: float = 0.8
    orientation_window_m: float = 0.25
    use_astar: bool = True
    goal_approach_join_m: float = 0.0
    goal_approach_max_angle_rad: float = 0.35

    def __post_init__(self) -> None:
        if not (isinstance(self.goal_approach_max_angle_rad, (int, float))
                and 0.0 <= self.goal_approach_max_angle_rad <= math.pi / 2):
            raise ValueError(f"goal_approach_max_angle_rad must be in [0, pi/2], got "
                             f"{self.goal_approach_max_angle_rad!r}")
        require_fields(self, non_negative=("default_tolerance", "cost_factor", "orientation_window_m",
                                           "goal_approach_join_m"))
        if not (math.isfinite(self.neutral_cost) and self.neutral_cost > 0):
            raise ValueError(f"neutral_cost must be > 0, got {self.neutral_cost!r}")


def navfn_cell_costs(costs: np.ndarray, config: NavfnConfig = NavfnConfig()) -> np.ndarray:
    """Traversal cost of every cell (float64); +inf where impassable."""
    c = np.asarray(costs)
    out = config.neutral_cost + config.cost_factor * c.astype(np.float64)
    out[c >= INSCRIBED_INFLATED_OBSTACLE] = np.inf
    if config.allow_unknown:
        out[c == NO_INFORMATION] = float(INSCRIBED_INFLATED_OBSTACLE)
    return out




def navfn_cost_table(config: NavfnConfig = NavfnConfig()) -> np.ndarray:
    """The traversal cost of each of the 256 costmap values (what navfn_cell_costs maps them to)."""
    return navfn_cell_costs(np.arange(256, dtype=np.uint8), config)


# A* tie-break: the heuristic is weighted by (1 + TIE_BREAK) so that among queue entries of
# equal g + h the one nearer the goal comes first; the path then costs at most (1 + 1e-10)
# times the optimum, far below what matters, yet above float64 rounding noise of the keys.
TIE_BREAK = 1e-10


@njit(cache=True, nogil=True, inline="always")
def _heap_put(heap, hkey, where, i, cell, key):  # pragma: no cover - compiled
    """Put ``cell`` with ``key`` in slot ``i`` of the search's binary heap and note the slot in ``where``."""
    heap[i] = cell
    hkey[i] = key
    where[cell] = i


@njit(cache=True, nogil=True)
def _search(costs, cost_lut, start, target_mask, n_targets, bx0, bx1, by0, by1, h_scale):
    """8-connected Dijkstra / A* over a (h, w) costmap grid from flat index ``start``.

    costs: (h, w) uint8 costmap values; a cell costs cost_lut[value] to enter
    (+inf = impassable), except the start cell, which always counts as
    passable (navfn clears the robot's cell). Reading the 1-byte grid through
    a 256-entry table instead of building a float cost grid keeps the search's
    working set small (the 0.05 m farm maps have 0.6 to 4 million cells).
    target_mask: (by1 - by0 + 1, bx1 - bx0 + 1) bool over the goal window.

    The queue is ordered by g + h with h = h_scale * (octile distance in cells
    from the cell to the target box [bx0..bx1] x [by0..by1]). With h_scale = 0
    this is plain Dijkstra; with h_scale <= the smallest cell cost the
    heuristic is consistent, so every popped cell has its exact potential and
    the result is the same optimal path, found after far fewer expansions.

    Returns (potential, parent): potential +inf where not finalised before the
    stop; parent = flat index of the previous cell (-1 at the start /
    unreached). Stops once ``n_targets`` cells of target_mask are final.
    """
    h, w = costs.shape
    n = h * w
    flat = costs.ravel()
    start_value = flat[start]
    flat[start] = 0                     # restored below; 0 is the cheapest, passable value
    pot = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int32)
    done = np.zeros(n, dtype=np.bool_)
    # indexed binary min-heap on key = g + h, with decrease-key (int32 indices: half the
    # memory traffic of int64; grids up to 2^31 cells)
    heap = np.empty(n, dtype=np.int32)
    hkey = np.empty(n)
    where = np.full(n, -1, dtype=np.int32)
    pot[start] = 0.0
    heap[0] = start
    hkey[0] = 0.0
    where[start] = 0
    size = 1
    offs = np.array([1, -1, w, -w, w + 1, -w + 1, w - 1, -w - 1])
    dxs = np.array([1, -1, 0, 0, 1, 1, -1, -1])
    dys = np.array([0, 0, 1, -1, 1, -1, 1, -1])
    inf = np.inf
    found = 0
    while size > 0:
        u = heap[0]
        size -= 1
        where[u] = -1
        if size > 0:
            last = heap[size]
            lkey = hkey[size]
            i = 0
            while True:
                l = 2 * i + 1
                if l >= size:
                    break
                c = l
                if l + 1 < size and hkey[l + 1] < hkey[l]:
                    c = l + 1
                if hkey[c] < lkey:
                    _heap_put(heap, hkey, where, i, heap[c], hkey[c])
                    i = c
                else:
                    break
            _heap_put(heap, hkey, where, i, last, lkey)
        done[u] = True
        uy = u // w
        ux = u - uy * w
        if bx0 <= ux <= bx1 and by0 <= uy <= by1 and target_mask[uy - by0, ux - bx0]:
            found += 1
            if found >= n_targets:
                break
        pu = pot[u]
        interior = 0 < ux < w - 1 and 0 < uy < h - 1
        for k in range(8):
            if not interior:
                vx = ux + dxs[k]
                vy = uy + dys[k]
                if vx < 0 or vx >= w or vy < 0 or vy >= h:
                    continue
            v = u + offs[k]
            if done[v]:
                continue
            cv = cost_lut[flat[v]]
            if cv == inf:
                continue
            if k >= 4:
                # diagonal: both side cells must be passable (no corner cutting)
                if cost_lut[flat[u + dxs[k]]] == inf or cost_lut[flat[u + dys[k] * w]] == inf:
                    continue
                nd = pu + cv * 1.4142135623730951
            else:
                nd = pu + cv
            if nd < pot[v]:
                pot[v] = nd
                parent[v] = u
                vy = v // w
                vx = v - vy * w
                ddx = max(bx0 - vx, 0, vx - bx1)
                ddy = max(by0 - vy, 0, vy - by1)
                key = nd + h_scale * (max(ddx, ddy) + 0.41421356237309515 * min(ddx, ddy))
                i = where[v]
                if i < 0:
                    i = size
                    size += 1
                while i > 0:
                    p = (i - 1) // 2
                    if hkey[p] > key:
                        _heap_put(heap, hkey, where, i, heap[p], hkey[p])
                        i = p
                    else:
                        break
                _heap_put(heap, hkey, where, i, v, key)
    flat[start] = start_value
    for i in range(n):
        if not done[i]:
            pot[i] = inf
    return pot.reshape(h, w), parent


def _orientations(xy: np.ndarray, goal_yaw: float, window_m: float) -> np.ndarray:
    n = len(xy)
    yaw = np.empty(n)
    if n == 1:
        yaw[0] = goal_yaw
        return yaw
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(xy[:, 0]), np.diff(xy[:, 1])))])
    lo = np.searchsorted(s, s - window_m, side="left")
    hi = np.searchsorted(s, s + window_m, side="right") - 1
    lo = np.clip(lo, 0, n - 1)
    hi = np.clip(hi, 0, n - 1)
    same = hi == lo
    hi = np.where(same, np.minimum(lo + 1, n - 1), hi)
    lo = np.where(hi == lo, np.maximum(hi - 1, 0), lo)
    d = xy[hi] - xy[lo]
    yaw[:] = np.arctan2(d[:, 1], d[:, 0])
    yaw[-1] = goal_yaw
    return wrap_angle(yaw)


class NavfnPlanner(GlobalPlanner):
    """navfn/NavfnROS equivalent; see the module docstring for the algorithm."""

    def __init__(self, config: NavfnConfig = NavfnConfig()):
        self.config = config
        self.last_potential: Optional[np.ndarray] = None   # for visualisation / debugging

    def make_plan(self, costmap, start, goal, tolerance_m: Optional[float] = None) -> Plan:
        """Plan on ``costmap`` (a Costmap2D, or anything with .spec and .costs).

        Returns an empty Plan with a reason when start or goal is off the map
        or no reachable cell lies within the tolerance of the goal.
        """
        start = as_pose(start)
        goal = as_pose(goal)
        tol = self.config.default_tolerance if tolerance_m is None else float(tolerance_m)
        if not (math.isfinite(tol) and tol >= 0):
            raise ValueError(f"tolerance_m must be a finite number >= 0, got {tolerance_m!r}")
        if self.config.goal_approach_join_m > 0:
            plan = self._approach_plan(costmap, start, goal, tol)
            if plan is not None:
                return plan
        return self._navfn_plan(costmap, start, goal, tol)

    def _approach_plan(self, costmap, start: Pose2D, goal: Pose2D, tol: float) -> Optional[Plan]:
        """The plan that joins the goal's heading line (module docstring), or None where it does not apply."""
        c = self.config
        ux, uy = math.cos(goal.yaw_rad), math.sin(goal.yaw_rad)
        dx, dy = goal.x_m - start.x_m, goal.y_m - start.y_m
        along = dx * ux + dy * uy                       # goal ahead of the robot, along the goal's heading
        if along <= c.goal_approach_join_m or math.hypot(dx, dy) <= 0.0:
            return None
        if abs(wrap_angle(math.atan2(dy, dx) - goal.yaw_rad)) > c.goal_approach_max_angle_rad:
            return None
        # the join point: on the line, goal_approach_join_m past the robot's foot point
        rest = along - c.goal_approach_join_m
        jx, jy = goal.x_m - rest * ux, goal.y_m - rest * uy
        spec = costmap.spec
        step = 0.5 * spec.resolution_m
        n = max(2, int(math.ceil(rest / step)) + 1)
        t = np.linspace(0.0, rest, n)
        lx, ly = jx + t * ux, jy + t * uy
        mx, my = spec.world_to_map(lx, ly)
        if not np.all(spec.in_bounds(mx, my)):
            return None
        if np.any(np.asarray(costmap.costs)[my, mx] >= INSCRIBED_INFLATED_OBSTACLE):
            return None
        head = self._navfn_plan(costmap, start, Pose2D(jx, jy, goal.yaw_rad), tol)
        if not head.ok:
            return None
        line = np.column_stack([lx, ly])
        xy = np.vstack([head.poses[:-1, :2], line])
        yaw = _orientations(xy, goal.yaw_rad, c.orientation_window_m)
        cost = head.cost + c.neutral_cost * rest / spec.resolution_m   # the line at (at least) neutral cost
        return Plan(np.column_stack([xy, yaw]), "", float(cost))

    def _navfn_plan(self, costmap, start: Pose2D, goal: Pose2D, tol: float) -> Plan:
        spec = costmap.spec
        sx, sy = (int(v) for v in spec.world_to_map(start.x_m, start.y_m))
        gx, gy = (int(v) for v in spec.world_to_map(goal.x_m, goal.y_m))
        if not spec.in_bounds(sx, sy):
            return Plan.empty(f"start ({start.x_m:.2f}, {start.y_m:.2f}) is off the costmap")
        tol_cells = int(math.floor(tol / spec.resolution_m + 1e-9))
        x0, x1 = max(0, gx - tol_cells), min(spec.width - 1, gx + tol_cells)
        y0, y1 = max(0, gy - tol_cells), min(spec.height - 1, gy + tol_cells)
        if x0 > x1 or y0 > y1:
            return Plan.empty(f"goal ({goal.x_m:.2f}, {goal.y_m:.2f}) is off the costmap")

        costs = np.array(costmap.costs, dtype=np.uint8, order="C")      # a copy: the search marks the start
        lut = navfn_cost_table(self.config)
        if spec.in_bounds(gx, gy) and (np.isfinite(lut[costs[gy, gx]]) or (gx, gy) == (sx, sy)):
            tx0 = tx1 = gx
            ty0 = ty1 = gy
            target = np.ones((1, 1), dtype=np.bool_)
        else:
            tx0, tx1, ty0, ty1 = x0, x1, y0, y1
            target = np.isfinite(lut[costs[y0:y1 + 1, x0:x1 + 1]])
            if tx0 <= sx <= tx1 and ty0 <= sy <= ty1:
                target[sy - ty0, sx - tx0] = True
        n_targets = int(target.sum())
        if n_targets == 0:
            return Plan.empty("the goal and every cell within the tolerance are obstacles")
        h_scale = (min(self.config.neutral_cost, float(INSCRIBED_INFLATED_OBSTACLE)) * (1.0 + TIE_BREAK)
                   if self.config.use_astar else 0.0)
        # the heuristic measures the distance to the target box (the goal cell, or the window)
        pot, parent = _search(costs, lut, sy * spec.width + sx, target, n_targets, tx0, tx1, ty0, ty1, h_scale)
        self.last_potential = pot

        # the end cell: the goal if reached, else the reachable cell nearest the goal in the window
        if spec.in_bounds(gx, gy) and np.isfinite(pot[gy, gx]):
            ex, ey = gx, gy
        else:
            wy, wx = np.mgrid[y0:y1 + 1, x0:x1 + 1]
            wp = pot[y0:y1 + 1, x0:x1 + 1]
            ok = np.isfinite(wp)
            if not ok.any():
                return Plan.empty(f"no reachable cell within {tol:.3f} m of the goal "
                                  f"({goal.x_m:.2f}, {goal.y_m:.2f})")
            cx, cy = spec.map_to_world(wx[ok], wy[ok])
            d2 = (cx - goal.x_m) ** 2 + (cy - goal.y_m) ** 2
            order = np.lexsort((wp[ok], d2))
            ex, ey = int(wx[ok][order[0]]), int(wy[ok][order[0]])

        cells = []
        idx = ey * spec.width + ex
        while idx >= 0:
            cells.append(idx)
            idx = parent[idx]
        cells = np.array(cells[::-1], dtype=np.int64)
        cx, cy = spec.map_to_world(cells % spec.width, cells // spec.width)
        xy = np.column_stack([cx, cy])
        xy[0] = (start.x_m, start.y_m)
        if (ex, ey) == (gx, gy):
            xy[-1] = (goal.x_m, goal.y_m)
        if len(xy) == 1:
            xy = np.vstack([xy, xy[-1:]])
        yaw = _orientations(xy, goal.yaw_rad, self.config.orientation_window_m)
        return Plan(np.column_stack([xy, yaw]), "", float(pot[ey, ex]))


register_global_planner(["navfn/NavfnROS", "navfn", "NavfnROS"], lambda config=NavfnConfig(): NavfnPlanner(config))
