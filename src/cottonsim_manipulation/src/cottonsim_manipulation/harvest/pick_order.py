"""The order of a stop's picks: the nearest target first, but never through another target.

Every pick starts and ends at the bin pose, so the order does not change the
arm's travel. It matters where a target lies in front of another: the vacuum is
on along the approach line (pre-grasp to grasp), and the nozzle takes the first
boll that comes within its capture radius. A target whose approach line passes
within ``clear_approach_radius_m`` of another target of the stop
(:func:`approach_blockers`) is picked after it (:func:`clear_approaches_first`);
otherwise the nozzle would catch the neighbour and leave the target on the
plant, believed picked (offline, seed 0, the 354 lane-facing bolls of 30 plants
on each side of row 1: 18 approaches took a neighbour first, and 17 of those
neighbours' own approaches took them). Among the targets whose way is clear
the given order (the nearest first) decides; where targets block each other in
a circle, it goes on.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Sequence, Set

import numpy as np

from cottonsim_common.vacuum_capture import CaptureConfig
from cottonsim_common.validation import require_number

CLEAR_MARGIN_M = 0.01      # the default clear radius: the capture radius + this, for the targets' position error [m]


@dataclass(frozen=True)
class PickOrderConfig:
    """clear_approach_radius_m: a target within this distance of another's approach line is picked
    first [m] (0: off); default the nozzle's capture radius + CLEAR_MARGIN_M."""

    clear_approach_radius_m: float = CaptureConfig().capture_radius_m + CLEAR_MARGIN_M

    def __post_init__(self) -> None:
        require_number("PickOrderConfig.clear_approach_radius_m", self.clear_approach_radius_m, 0.0, 0.5)


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
