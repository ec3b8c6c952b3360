"""The order in which the bolls of one stop are picked: short joint travel of the arm.

Each target comes with the joint configuration the approach planner chose for it
(its pre-grasp, ApproachPlan.q_pregrasp_rad). The distance between two
configurations is the joint travel sum_j |q_j - q'_j| [rad], the measure the
approach planner minimises. The order is an open path from the arm's current
joints through every target:

1. greedy nearest-next: from the current joints, always the nearest unvisited
   target (ties go to the lower input index, so the order is deterministic);
2. 2-opt (``two_opt_passes`` > 0): reverse any stretch of the path that makes
   it shorter, until no reversal helps or the passes run out. Greedy alone
   can leave long jumps back at its end; 2-opt removes the crossings, and for
   the few (<= ~20) bolls of a stop it costs well under a millisecond.

The start (the current joints) stays first; the path does not return.

3. clear approaches (``clear_approach_radius_m`` > 0): the vacuum is on along the approach
   line, and the nozzle takes the first boll that comes within its capture radius. A target
   whose approach line passes that close to another target of the stop (``approach_blockers``)
   is picked after it (``clear_approaches_first``): otherwise the nozzle would catch the
   neighbour and leave the target on the plant, believed picked. The travel order decides
   among the targets whose way is clear; where targets block each other in a circle, the
   travel order goes on.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Sequence, Set

import numpy as np

from cottonsim_common.kinematics.ur5e import NUM_JOINTS, joint_vector
from cottonsim_common.vacuum_capture import CaptureConfig
from cottonsim_common.validation import require_number

CLEAR_MARGIN_M = 0.01      # the default clear radius: the capture radius + this, for the targets' position error [m]


@dataclass(frozen=True)
class PickOrderConfig:
    """two_opt_passes: full 2-opt sweeps over the greedy path at most (0: greedy only).
    clear_approach_radius_m: a target within this distance of another's approach line is picked
    first [m] (0: off); default the nozzle's capture radius + CLEAR_MARGIN_M."""

    two_opt_passes: int = 20
    clear_approach_radius_m: float = CaptureConfig().capture_radius_m + CLEAR_MARGIN_M

    def __post_init__(self) -> None:
        passes = self.two_opt_passes
        if isinstance(passes, bool) or not isinstance(passes, (int, np.integer)) or not (0 <= passes <= 1000):
            raise ValueError(f"PickOrderConfig.two_opt_passes must be an integer in [0, 1000], got {passes!r}")
        require_number("PickOrderConfig.clear_approach_radius_m", self.clear_approach_radius_m, 0.0, 0.5)


@dataclass(frozen=True)
class PickOrder:
    """target_ids in pick order; joint_travel_rad of the path from the current joints through them."""

    target_ids: List[int]
    joint_travel_rad: float


def path_joint_travel_rad(q_current_rad, joints_rad) -> float:
    """Joint travel [rad] of the path current -> joints_rad[0] -> joints_rad[1] -> ..."""
    q0 = joint_vector(q_current_rad, "current joints")
    q = np.asarray(joints_rad, dtype=float).reshape(-1, NUM_JOINTS)
    if not len(q):
        return 0.0
    path = np.vstack([q0, q])
    return float(np.abs(np.diff(path, axis=0)).sum())


def order_picks(target_ids: Sequence[int], target_joints_rad, q_current_rad,
                config: PickOrderConfig = PickOrderConfig()) -> PickOrder:
    """Pick order of the targets (ids with their chosen joints, (N, 6)) from the current joints.

    ValueError on malformed input (NaN, wrong shapes, repeated ids)."""
    ids = [int(i) for i in target_ids]
    if len(set(ids)) != len(ids):
        raise ValueError(f"target ids must be unique, got {ids}")
    q = np.asarray(target_joints_rad, dtype=float)
    if q.size == 0 and not ids:
        return PickOrder([], 0.0)
    if q.ndim != 2 or q.shape != (len(ids), NUM_JOINTS) or not np.all(np.isfinite(q)):
        raise ValueError(f"target joints must be finite, one row of {NUM_JOINTS} per target id "
                         f"({len(ids)} ids), got shape {q.shape}")
    q0 = joint_vector(q_current_rad, "current joints")
    nodes = np.vstack([q0, q])                                              # node 0: the start
    dist = np.abs(nodes[:, None, :] - nodes[None, :, :]).sum(axis=2)
    path = _greedy(dist)
    if config.two_opt_passes:
        path = _two_opt(path, dist, config.two_opt_passes)
    order = [ids[k - 1] for k in path[1:]]
    travel = float(sum(dist[a, b] for a, b in zip(path[:-1], path[1:])))
    return PickOrder(order, travel)


def _greedy(dist: np.ndarray) -> List[int]:
    n = len(dist)
    path = [0]
    left = list(range(1, n))
    while left:
        here = path[-1]
        nearest = min(left, key=lambda k: (dist[here, k], k))
        path.append(nearest)
        left.remove(nearest)
    return path


def _two_opt(path: List[int], dist: np.ndarray, passes: int) -> List[int]:
    """Open-path 2-opt with a fixed start: reverse path[i..j] when that shortens it."""
    path = list(path)
    n = len(path)
    for _ in range(passes):
        improved = False
        for i in range(1, n - 1):
            for j in range(i + 1, n):
                a, b = path[i - 1], path[i]
                c = path[j]
                d = path[j + 1] if j + 1 < n else None
                before = dist[a, b] + (dist[c, d] if d is not None else 0.0)
                after = dist[a, c] + (dist[b, d] if d is not None else 0.0)
                if after < before - 1e-12:
                    path[i:j + 1] = path[i:j + 1][::-1]
                    improved = True
        if not improved:
            break
    return path


def approach_blockers(target_ids: Sequence[int], positions_m, line_starts_m, line_ends_m,
                      radius_m: float) -> Dict[int, Set[int]]:
    """For each target with an approach line: the other targets whose centre lies within radius_m of it.

    target_ids (N,) with positions_m (N, 3); line_starts_m / line_ends_m (N, 3): the nozzle tip's
    approach segment of each target (pre-grasp to grasp), NaN rows for targets without one; one frame."""
    ids = [int(i) for i in target_ids]
    p = np.asarray(positions_m, dtype=float).reshape(-1, 3)
    a = np.asarray(line_starts_m, dtype=float).reshape(-1, 3)
    b = np.asarray(line_ends_m, dtype=float).reshape(-1, 3)
    if not (len(ids) == len(p) == len(a) == len(b)):
        raise ValueError(f"approach_blockers: {len(ids)} ids, {len(p)} positions, {len(a)} line starts, "
                         f"{len(b)} line ends")
    if not np.all(np.isfinite(p)):
        raise ValueError("approach_blockers: target positions contain NaN or infinity")
    out: Dict[int, Set[int]] = {}
    for k, target in enumerate(ids):
        if not (np.all(np.isfinite(a[k])) and np.all(np.isfinite(b[k]))):
            continue
        seg = b[k] - a[k]
        length2 = float(seg @ seg)
        u = np.clip((p - a[k]) @ seg / length2, 0.0, 1.0) if length2 > 0.0 else np.zeros(len(p))
        distance = np.linalg.norm(a[k] + u[:, None] * seg - p, axis=1)
        out[target] = {ids[j] for j in np.flatnonzero(distance <= radius_m) if j != k}
    return out


def clear_approaches_first(order_ids: Sequence[int], blockers: Dict[int, Set[int]]) -> List[int]:
    """order_ids reordered so that a target comes after the targets of the list on its approach line
    (blockers, from approach_blockers): each time the first of the remaining order whose blockers are
    all picked (the first one left when they block each other in a circle)."""
    left = [int(i) for i in order_ids]
    if len(set(left)) != len(left):
        raise ValueError(f"target ids must be unique, got {left}")
    out: List[int] = []
    while left:
        pending = set(left)
        clear = next((t for t in left if not (blockers.get(t, set()) & pending - {t})), left[0])
        out.append(clear)
        left.remove(clear)
    return out
