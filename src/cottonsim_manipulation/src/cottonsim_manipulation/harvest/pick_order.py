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
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List, Sequence

import numpy as np

from cottonsim_common.kinematics.ur5e import NUM_JOINTS, joint_vector


@dataclass(frozen=True)
class PickOrderConfig:
    """two_opt_passes: full 2-opt sweeps over the greedy path at most (0: greedy only)."""

    two_opt_passes: int = 20

    def __post_init__(self) -> None:
        passes = self.two_opt_passes
        if isinstance(passes, bool) or not isinstance(passes, (int, np.integer)) or not (0 <= passes <= 1000):
            raise ValueError(f"PickOrderConfig.two_opt_passes must be an integer in [0, 1000], got {passes!r}")


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
