"""Arm-plant contacts: every time the UR5e starts touching a plant's stem, branch or leaf.

Stems and main branches are collision geometry for the arm (a harvest aims
at zero arm-stem contacts); leaves are soft (the arm may brush them). The
simulator's arm is kinematic, so nothing stops it: this module counts.

Geometry (world frame, metres): the arm is its nine link capsules
(cottonsim_common.kinematics.arm_capsules, unpadded, the nozzle's last
``nozzle_tip_allowance_m`` left out as the planner leaves it out: it reaches
into the boll); each plant is its woody capsules and leaf spheres
(farm.plant_obstacles). A link touches a stem or branch when the segments
are closer than the sum of the radii, a leaf when the link's segment comes
within the link radius plus the leaf sphere's radius of its centre.

Counting, like the base's plant contacts (physics.ode_world): a contact
event is the start of a touching episode of one (arm link, plant, kind)
pair, kind 'stem' (stem or main branch) or 'leaf'. A pair that was apart
for at most ``rearm_s`` continues its episode (flicker is one event).
``update`` is called with the arm's capsules every ``check_period_s`` of
sim time at most (the caller decides; the Simulator steps it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, List, Set, Tuple

import numpy as np

from cottonsim_common.capsules import point_segment_distance, segment_segment_distance
from cottonsim_common.kinematics.arm_capsules import ARM_LINKS, ArmCollisionConfig
from cottonsim_common.validation import require_bool, require_number
from cottonsim_world.farm.plant_obstacles import WOODY_KIND_NAMES, PlantObstacles

KINDS = ("stem", "leaf")


@dataclass(frozen=True)
class ArmContactConfig:
    """The arm-plant contact counter (sim.yaml 'arm_contacts').

    enabled: count at all (false: no checks, no cost).
    check_period_s: sim time between two checks [s]; 0 = every physics step. The default, 10 ms (the
        rate of the arm's position follower), lets a link moving at 1 m/s travel 1 cm between checks,
        less than the thinnest touching zone (nozzle + branch: 5 cm across).
    rearm_s: a (link, plant, kind) pair apart for longer than this starts a new event [s].
    nozzle_tip_allowance_m: the nozzle's last part, not counted (it reaches into the boll) [m].
    """

    enabled: bool = True
    check_period_s: float = 0.01
    rearm_s: float = 0.1
    nozzle_tip_allowance_m: float = 0.03

    def __post_init__(self) -> None:
        require_bool("ArmContactConfig.enabled", self.enabled)
        for name, high in (("check_period_s", 1.0), ("rearm_s", 10.0), ("nozzle_tip_allowance_m", 0.15)):
            require_number(f"ArmContactConfig.{name}", getattr(self, name), 0.0, high)

    def arm_shape(self) -> ArmCollisionConfig:
        """The link capsules counted: the UR5e's, unpadded."""
        return ArmCollisionConfig(padding_m=0.0, nozzle_tip_allowance_m=self.nozzle_tip_allowance_m)


@dataclass(frozen=True)
class ArmContactEvent:
    """An arm link started touching a plant.

    kind: 'stem' (the stem or a main branch) or 'leaf'; part: 'stem', 'branch' or 'leaf';
    link: one of ARM_LINKS; point_m: the point of the link's axis nearest the plant part (world);
    depth_m: how far the surfaces overlap at the first check of the touch [m].
    """

    stamp_s: float
    plant_id: int
    kind: str
    part: str
    link: str
    point_m: Tuple[float, float, float]
    depth_m: float


def _nearest_on_segment(x: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    d = q - p
    dd = float(d @ d)
    t = 0.0 if dd < 1e-18 else min(1.0, max(0.0, float((x - p) @ d) / dd))
    return p + t * d


class ArmContactCounter:
    """Counts arm-plant contact events (see the module docstring)."""

    def __init__(self, obstacles: PlantObstacles, config: ArmContactConfig = ArmContactConfig()):
        if not isinstance(obstacles, PlantObstacles):
            raise ValueError(f"obstacles must be a PlantObstacles, got {type(obstacles).__name__}")
        if not isinstance(config, ArmContactConfig):
            raise ValueError(f"config must be an ArmContactConfig, got {type(config).__name__}")
        self.obstacles = obstacles
        self.config = config
        self.link_radius_m = config.arm_shape().radii_m
        self._reach_m = 0.0
        self._last_touch_s: Dict[Tuple[int, int, int], float] = {}
        self.totals: Dict[str, int] = {kind: 0 for kind in KINDS}
        self.plants_touched: Set[int] = set()
        self.last_check_s = -math.inf

    def due(self, now_s: float) -> bool:
        """Whether a check is due at now_s (check_period_s after the last one)."""
        return self.config.enabled and now_s >= self.last_check_s + self.config.check_period_s - 1e-9

    def near_plants(self, centre_m: np.ndarray, radius_m: float) -> bool:
        """Broad phase: whether any plant may touch a sphere (world centre, radius [m]) holding the arm's capsules
        (their link radii included). When not, a check has nothing to find: ``update_apart`` records it."""
        return len(self.obstacles.rows_near(centre_m, radius_m)) > 0

    def update_apart(self, now_s: float) -> None:
        """A check at now_s that found the arm away from every plant (what ``update`` would find)."""
        self.last_check_s = now_s

    def update(self, now_s: float, start_m: np.ndarray, end_m: np.ndarray) -> List[ArmContactEvent]:
        """Check the arm's link capsules (9, 3) start / end (world) at now_s; the new contact events."""
        start = np.asarray(start_m, dtype=float).reshape(len(ARM_LINKS), 3)
        end = np.asarray(end_m, dtype=float).reshape(len(ARM_LINKS), 3)
        if not (np.isfinite(start).all() and np.isfinite(end).all()):
            raise ValueError("arm capsules contain NaN or infinity")
        self.last_check_s = now_s
        touching = self._touching(start, end)
        events = []
        for key, (point, depth, part) in sorted(touching.items()):
            last = self._last_touch_s.get(key)
            self._last_touch_s[key] = now_s
            if last is not None and now_s - last <= self.config.rearm_s + 1e-9:
                continue
            link, plant, kind = key
            self.totals[KINDS[kind]] += 1
            self.plants_touched.add(plant)
            events.append(ArmContactEvent(now_s, plant, KINDS[kind], part, ARM_LINKS[link],
                                          tuple(float(v) for v in point), depth))
        return events

    def _touching(self, start: np.ndarray, end: np.ndarray) -> Dict[Tuple[int, int, int], Tuple]:
        """(link, plant, kind) -> (point, depth, part) of every pair touching now (deepest per pair)."""
        obs = self.obstacles
        radius = self.link_radius_m
        # broad phase: the plants within reach of the arm's bounding sphere
        lo, hi = np.minimum(start, end).min(axis=0), np.maximum(start, end).max(axis=0)
        centre = 0.5 * (lo + hi)
        bound = 0.5 * float(np.linalg.norm(hi - lo)) + float(radius.max())
        found: Dict[Tuple[int, int, int], Tuple] = {}
        plants = obs.rows_near(centre, bound)
        if not len(plants):
            return found
        woody, leaves = obs.rows_of(plants)
        # the parts inside the arm's bounding box grown by the thickest link
        grow = float(radius.max())
        lo, hi = lo - grow, hi + grow
        ws, we, wr = obs.woody_start_m[woody], obs.woody_end_m[woody], obs.woody_radius_m[woody, None]
        woody = woody[np.all((np.minimum(ws, we) - wr <= hi) & (np.maximum(ws, we) + wr >= lo), axis=1)]
        leaves = leaves[np.all(np.abs(obs.leaf_centre_m[leaves] - 0.5 * (lo + hi))
                               <= 0.5 * (hi - lo) + obs.leaf_radius_m[leaves, None], axis=1)]
        if len(woody):
            d = segment_segment_distance(start[:, None], end[:, None], obs.woody_start_m[woody][None],
                                         obs.woody_end_m[woody][None])
            overlap = radius[:, None] + obs.woody_radius_m[woody][None] - d
            for li, wi in zip(*np.nonzero(overlap > 0.0)):
                w = woody[wi]
                key = (int(li), int(obs.woody_plant[w]), 0)
                depth = float(overlap[li, wi])
                if key not in found or depth > found[key][1]:
                    mid = 0.5 * (obs.woody_start_m[w] + obs.woody_end_m[w])
                    found[key] = (_nearest_on_segment(mid, start[li], end[li]), depth,
                                  WOODY_KIND_NAMES[int(obs.woody_kind[w])])
        if len(leaves):
            c = obs.leaf_centre_m[leaves]
            d = point_segment_distance(c[None], start[:, None], end[:, None])
            overlap = radius[:, None] + obs.leaf_radius_m[leaves][None] - d
            for li, ci in zip(*np.nonzero(overlap > 0.0)):
                key = (int(li), int(obs.leaf_plant[leaves[ci]]), 1)
                depth = float(overlap[li, ci])
                if key not in found or depth > found[key][1]:
                    found[key] = (_nearest_on_segment(c[ci], start[li], end[li]), depth, "leaf")
        return found
