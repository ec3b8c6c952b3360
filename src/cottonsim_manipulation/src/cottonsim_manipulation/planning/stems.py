"""The plants' stems as obstacles of the approach plan, from where the robot estimates them.

The robot does not perceive stems, but it estimates each boll's stem (the harvester's 'plant'
outward model: on the row's line, at the centre of the boll's plant along the row). A stem is a
vertical capsule from the ground up to the plants' height; every boll of a plant estimates the
same stem, so estimates closer than ``stem_merge_distance_m`` become one stem at their mean.
The capsules go to plan_approach as its ``obstacles`` (in the arm's base frame:
``stem_obstacles(...).transformed(arm_T_frame)`` when the stems are given in another frame,
or ``+`` with other obstacles).

Frames: any frame whose z axis points up (base_link, odom, the arm's base frame); metres.
"""
from __future__ import annotations

import numpy as np

from cottonsim_common.capsules import CapsuleSet
from cottonsim_manipulation.planning.approach import ApproachConfig


def merge_stems(stems_xy_m, merge_distance_m: float) -> np.ndarray:
    """Stem estimates (N, 2) [m] with those closer than merge_distance_m joined: each estimate,
    in the given order, joins the first group whose mean is within the distance, else starts one;
    returns the groups' means (M, 2), in the order the groups started."""
    xy = np.asarray(stems_xy_m, dtype=float)
    if xy.size == 0:
        return np.zeros((0, 2))
    if xy.ndim != 2 or xy.shape[1] != 2 or not np.all(np.isfinite(xy)):
        raise ValueError(f"stem positions must be (N, 2) finite numbers [m], got shape {xy.shape}")
    sums, counts = [], []
    for point in xy:
        for k, (total, count) in enumerate(zip(sums, counts)):
            if np.linalg.norm(total / count - point) <= merge_distance_m:
                sums[k] = total + point
                counts[k] = count + 1
                break
        else:
            sums.append(point.copy())
            counts.append(1)
    return np.array(sums) / np.array(counts, dtype=float)[:, None]


def stem_obstacles(stems_xy_m, ground_z_m: float, config: ApproachConfig = ApproachConfig(),
                   name: str = "stem") -> CapsuleSet:
    """Vertical capsules (radius config.stem_radius_m) from the ground (z = ground_z_m) up
    config.stem_height_m at the estimated stems (N, 2) [m], merged (merge_stems with
    config.stem_merge_distance_m); named '<name>_<k>'. ValueError on malformed input."""
    if not isinstance(ground_z_m, (int, float)) or isinstance(ground_z_m, bool) or not np.isfinite(ground_z_m):
        raise ValueError(f"ground_z_m must be a finite number [m], got {ground_z_m!r}")
    xy = merge_stems(stems_xy_m, config.stem_merge_distance_m)
    feet = np.column_stack([xy, np.full(len(xy), float(ground_z_m))])
    tops = feet + np.array([0.0, 0.0, config.stem_height_m])
    return CapsuleSet(feet, tops, np.full(len(xy), config.stem_radius_m), tuple(f"{name}_{k}" for k in range(len(xy))))
