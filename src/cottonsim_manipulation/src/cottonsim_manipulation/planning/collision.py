"""Collision checks of the UR5e: a capsule per link against plants, the robot's body and itself.

All geometry is in the arm's base frame (the UR 'base', DH frame 0; ur5e_base in
the URDF), metres.

* The arm is nine capsules on the DH frames (ArmCollisionConfig): base column,
  shoulder drum, upper-arm tube, elbow drum, forearm tube, the three wrists and
  the vacuum nozzle on the flange. The radii are those of the UR5e's housings
  and tubes as the robot description draws them (make_urdf.py); each capsule
  is grown by ``padding_m`` against obstacles and the body.
* Plants are capsules (stems and main branches, CapsuleSet); leaves are soft
  and not obstacles. The nozzle's last ``nozzle_tip_allowance_m`` is left out:
  it reaches into the boll and may touch the boll's stalk.
* The robot's own body is oriented boxes (BoxSet; robot_body.py builds them
  from the URDF). The arm's base column stands on the top plate and is not
  checked against the body.
* Self-collision: every pair of arm capsules at least three apart along the
  chain (neighbours and next-but-one neighbours touch by construction).

A path is checked at configurations no more than ``step_rad`` apart in any
joint along the straight joint-space segments between its waypoints (the path
a JointTrajectory follows). Between two samples a point of the arm moves at
most sum_j R_j |dq_j|, R_j its distance from joint j's axis (<= ~1.1 m for the
shoulder joints, ~0.3 m for the wrists), so keep step_rad * ~1 m below the
padding plus the thickness of the thinnest obstacle.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

import numpy as np

from cottonsim_common.capsules import (CapsuleSet, point_segment_distance,
                                       segment_segment_distance)
from cottonsim_common.kinematics.arm_capsules import (ARM_LINKS, ArmCollisionConfig,
                                                      arm_capsule_segments)
from cottonsim_common.kinematics.ur5e import Ur5eKinematics
from cottonsim_common.validation import require_instance
from cottonsim_manipulation.planning.trajectory import interpolate_path, path_of

SELF_COLLISION_MIN_GAP = 3


@dataclass(frozen=True)
class BoxSet:
    """Oriented boxes: centre_m (M, 3) [m], rotation (M, 3, 3) (box axes as columns),
    half_extents_m (M, 3) [m]."""

    centre_m: np.ndarray
    rotation: np.ndarray
    half_extents_m: np.ndarray
    names: Tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        centre = np.asarray(self.centre_m, dtype=float)
        m = centre.size // 3 if centre.ndim else 0
        if centre.shape != (m, 3) or np.shape(self.rotation) != (m, 3, 3) or np.shape(self.half_extents_m) != (m, 3):
            raise ValueError(
                f"BoxSet needs centre_m (M, 3), rotation (M, 3, 3) and half_extents_m (M, 3), got "
                f"{np.shape(self.centre_m)}, {np.shape(self.rotation)}, {np.shape(self.half_extents_m)}"
            )
        rot = np.asarray(self.rotation, dtype=float)
        half = np.asarray(self.half_extents_m, dtype=float)
        for what, arr in (("centre_m", centre), ("rotation", rot), ("half_extents_m", half)):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"BoxSet.{what} contains NaN or infinity")
        if np.any(half < 0.0):
            raise ValueError("BoxSet.half_extents_m must be >= 0")
        if m and np.abs(np.einsum("mji,mjk->mik", rot, rot) - np.eye(3)).max() > 1e-6:
            raise ValueError("BoxSet.rotation must hold rotation matrices")
        names = tuple(self.names) if self.names else tuple(f"box_{i}" for i in range(m))
        if len(names) != m:
            raise ValueError(f"BoxSet has {m} boxes but {len(names)} names")
        object.__setattr__(self, "centre_m", centre.reshape(m, 3))
        object.__setattr__(self, "rotation", rot.reshape(m, 3, 3))
        object.__setattr__(self, "half_extents_m", half.reshape(m, 3))
        object.__setattr__(self, "names", names)

    def __len__(self) -> int:
        return len(self.names)

    @classmethod
    def empty(cls) -> "BoxSet":
        return cls(np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3)), ())

    @classmethod
    def axis_aligned(cls, boxes: Sequence[Tuple[Sequence[float], Sequence[float], str]]) -> "BoxSet":
        """From (min corner, max corner, name) tuples of axis-aligned boxes."""
        if not boxes:
            return cls.empty()
        lo, hi, names = zip(*boxes)
        lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
        if np.any(hi < lo):
            raise ValueError("a box's max corner lies below its min corner")
        return cls((lo + hi) / 2.0, np.repeat(np.eye(3)[None], len(names), axis=0), (hi - lo) / 2.0, names)


def segment_box_distance(p, q, centre, rotation, half, iterations: int = 32) -> np.ndarray:
    """Distance from segments p-q to solid oriented boxes (arrays broadcast on the leading axes) [m].

    The distance of a point moving along the segment to a convex box is convex
    in the segment parameter, so a golden-section search finds its minimum.
    """
    rt = np.swapaxes(rotation, -1, -2)
    lp = np.einsum("...ij,...j->...i", rt, p - centre)
    lq = np.einsum("...ij,...j->...i", rt, q - centre)

    step = lq - lp

    def dist(t):
        out = np.maximum(np.abs(lp + step * t[..., None]) - half, 0.0)
        return np.sqrt(out[..., 0] ** 2 + out[..., 1] ** 2 + out[..., 2] ** 2)

    shape = np.broadcast_shapes(lp.shape[:-1], lq.shape[:-1], np.shape(half)[:-1])
    lo, hi = np.zeros(shape), np.ones(shape)
    g = (math.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1, f2 = dist(x1), dist(x2)
    for _ in range(iterations):
        left = f1 <= f2                      # the minimum lies in [lo, x2], else in [x1, hi]
        hi = np.where(left, x2, hi)
        lo = np.where(left, lo, x1)
        new_x1 = np.where(left, hi - g * (hi - lo), x2)
        new_x2 = np.where(left, x1, lo + g * (hi - lo))
        f_probe = dist(np.where(left, new_x1, new_x2))
        f1, f2 = np.where(left, f_probe, f2), np.where(left, f1, f_probe)
        x1, x2 = new_x1, new_x2
    return np.minimum(np.minimum(dist(lo), dist(hi)), np.minimum(f1, f2))


# ----------------------------------------------------------------------------- the arm
@dataclass(frozen=True)
class Contact:
    """A collision found: at path sample `sample`, arm capsule `link` against `other`.

    kind: 'obstacle' (a plant capsule), 'body' (a box of the robot) or 'self'.
    clearance_m: surface distance with the padding (negative: overlap) [m].
    """

    sample: int
    link: str
    other: str
    kind: str
    clearance_m: float

    def __str__(self) -> str:
        return f"{self.link} hits {self.kind} {self.other} at sample {self.sample} ({self.clearance_m * 1000:.1f} mm)"


class ArmCollisionModel:
    """The UR5e's capsules with the robot's body boxes; checks configurations and paths."""

    def __init__(self, config: Optional[ArmCollisionConfig] = None, body: Optional[BoxSet] = None,
                 kinematics: Optional[Ur5eKinematics] = None):
        self.config = config or ArmCollisionConfig()
        self.body = body if body is not None else BoxSet.empty()
        require_instance("body", self.body, BoxSet)
        self.kinematics = kinematics or Ur5eKinematics()
        n = len(ARM_LINKS)
        self.self_pairs = np.array([(i, j) for i in range(n) for j in range(i + SELF_COLLISION_MIN_GAP, n)])
        self.body_links = np.arange(1, n)          # the base column stands on the plate
        self._radii = self.config.radii_m

    def capsules(self, q_rad: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Segment ends (K, 9, 3), (K, 9, 3) of ARM_LINKS for joints (K, 6) [rad]."""
        return arm_capsule_segments(q_rad, self.config, self.kinematics)

    def clearances(self, q_rad: np.ndarray, obstacles: Optional[CapsuleSet] = None):
        """Surface distances with padding [m] at each configuration (K, 6): obstacle (K, 9, N),
        body (K, 8, M) for links 1.., self (K, pairs). Pairs that a bounding test shows to be
        clear get +inf instead of their distance."""
        if obstacles is not None and not isinstance(obstacles, CapsuleSet):
            raise ValueError(f"obstacles must be a CapsuleSet, got {type(obstacles).__name__}")
        start, end = self.capsules(q_rad)
        c = self.config
        grown = self._radii + c.padding_m
        k, n_links = start.shape[0], len(ARM_LINKS)
        obstacle = np.full((k, n_links, len(obstacles) if obstacles is not None else 0), np.inf)
        if obstacle.size:
            # Broad phase: spheres round each segment's midpoint.
            mid_a, half_a = (start + end) / 2.0, np.linalg.norm(end - start, axis=-1) / 2.0
            mid_o = (obstacles.start_m + obstacles.end_m) / 2.0
            half_o = np.linalg.norm(obstacles.end_m - obstacles.start_m, axis=-1) / 2.0
            gap = np.linalg.norm(mid_a[:, :, None] - mid_o[None, None], axis=-1)
            near = gap < (half_a + grown)[:, :, None] + (half_o + obstacles.radius_m)[None, None]
            if near.any():
                ki, li, oi = np.nonzero(near)
                d = segment_segment_distance(start[ki, li], end[ki, li], obstacles.start_m[oi], obstacles.end_m[oi])
                obstacle[ki, li, oi] = d - grown[li] - obstacles.radius_m[oi]
        body = np.full((k, len(self.body_links), len(self.body)), np.inf)
        if body.size:
            # Broad phase: the capsule's bounding box in each box's frame against the box.
            rt = np.swapaxes(self.body.rotation, -1, -2)[None, None]               # (1, 1, M, 3, 3)
            lp = np.einsum("...ij,...j->...i", rt, start[:, self.body_links, None] - self.body.centre_m)
            lq = np.einsum("...ij,...j->...i", rt, end[:, self.body_links, None] - self.body.centre_m)
            r = grown[self.body_links][None, :, None, None]
            half = self.body.half_extents_m[None, None]
            near = np.all((np.minimum(lp, lq) - r < half) & (np.maximum(lp, lq) + r > -half), axis=-1)
            if near.any():
                ki, li, bi = np.nonzero(near)
                exact = segment_box_distance(lp[ki, li, bi], lq[ki, li, bi], 0.0, np.eye(3),
                                             self.body.half_extents_m[bi])
                body[ki, li, bi] = exact - grown[self.body_links[li]]
        i, j = self.self_pairs[:, 0], self.self_pairs[:, 1]
        self_d = segment_segment_distance(start[:, i], end[:, i], start[:, j], end[:, j])
        selfc = self_d - (self._radii[i] + self._radii[j] + 2.0 * c.self_padding_m)
        return obstacle, body, selfc

    def contacts(self, q_rad: np.ndarray, obstacles: Optional[CapsuleSet] = None,
                 first_only: bool = False) -> List[Contact]:
        """Every collision at configurations (K, 6) (or only the first sample's), ordered by sample."""
        obstacle, body, selfc = self.clearances(q_rad, obstacles)
        found: List[Contact] = []
        hit_samples = np.flatnonzero(
            (obstacle < 0).reshape(len(obstacle), -1).any(axis=1)
            | (body < 0).reshape(len(body), -1).any(axis=1)
            | (selfc < 0).any(axis=1)
        )
        for kk in hit_samples[:1] if first_only else hit_samples:
            for li, oi in np.argwhere(obstacle[kk] < 0):
                found.append(Contact(int(kk), ARM_LINKS[li], obstacles.names[oi], "obstacle",
                                     float(obstacle[kk, li, oi])))
            for li, bi in np.argwhere(body[kk] < 0):
                found.append(Contact(int(kk), ARM_LINKS[self.body_links[li]], self.body.names[bi], "body",
                                     float(body[kk, li, bi])))
            for pi in np.flatnonzero(selfc[kk] < 0):
                a, b = self.self_pairs[pi]
                found.append(Contact(int(kk), ARM_LINKS[a], ARM_LINKS[b], "self", float(selfc[kk, pi])))
        return found

    def in_collision(self, q_rad: np.ndarray, obstacles: Optional[CapsuleSet] = None) -> np.ndarray:
        """(K,) True where configuration k collides with anything."""
        obstacle, body, selfc = self.clearances(q_rad, obstacles)
        k = len(selfc)
        return ((obstacle < 0).reshape(k, -1).any(axis=1) | (body < 0).reshape(k, -1).any(axis=1)
                | (selfc < 0).any(axis=1))

    def first_collision(self, path, obstacles: Optional[CapsuleSet] = None,
                        step_rad: float = 0.02, chunk: int = 24) -> Optional[Contact]:
        """The first collision along a JointTrajectory or (N, 6) waypoints, checked every
        step_rad (Contact.sample = index along the interpolated path), or None. The
        deepest contact of the first colliding sample is returned."""
        samples = interpolate_path(path_of(path), step_rad)
        for first in range(0, len(samples), chunk):
            hits = self.contacts(samples[first:first + chunk], obstacles, first_only=True)
            if hits:
                worst = min(hits, key=lambda h: h.clearance_m)
                return Contact(worst.sample + first, worst.link, worst.other, worst.kind, worst.clearance_m)
        return None

    def path_is_collision_free(self, path, obstacles: Optional[CapsuleSet] = None, step_rad: float = 0.02) -> bool:
        """True when no configuration along the path (checked every step_rad) collides."""
        return self.first_collision(path, obstacles, step_rad) is None


def path_is_collision_free(self, path, obstacles: Optional[CapsuleSet] = None, step_rad: float = 0.02) -> bool:
        samples = interpolate_path(path_of(path), step_rad)
        return not bool(self.in_collision(samples, obstacles).any())


def path_is_collision_free(trajectory, obstacles: Optional[CapsuleSet], step_rad: float,
                           model: Optional[ArmCollisionModel] = None) -> bool:
    """True when the arm's path (JointTrajectory or (N, 6) waypoints), checked every step_rad,
    hits no obstacle capsule, no body box of `model` and not itself."""
    return (model or ArmCollisionModel()).path_is_collision_free(trajectory, obstacles, step_rad)
