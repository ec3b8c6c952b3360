"""Capsules and the distances between segments: the geometry of arm-plant collision checks.

A capsule is a segment grown by a radius. The robot side (the arm's planner,
cottonsim_manipulation.planning.collision) and the simulator (the arm-plant
contact counter, cottonsim_world.robot.arm_contacts) both measure the arm's
link capsules against the plants' stems and branches with these functions,
so the two cannot disagree about what touches. Lengths in metres.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence, Tuple

import numpy as np

_EPS = 1e-12


def _as_points(values, count: int, what: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float).reshape(count, 3) if count else np.zeros((0, 3))
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} contains NaN or infinity")
    return arr


@dataclass(frozen=True)
class CapsuleSet:
    """Capsules: segments start_m -> end_m (N, 3) [m] grown by radius_m (N,) [m]."""

    start_m: np.ndarray
    end_m: np.ndarray
    radius_m: np.ndarray
    names: Tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        start = np.asarray(self.start_m, dtype=float)
        n = start.size // 3 if start.ndim else 0
        if start.shape not in ((n, 3),) or np.shape(self.end_m) != (n, 3) or np.shape(self.radius_m) != (n,):
            raise ValueError(
                f"CapsuleSet needs start_m and end_m (N, 3) and radius_m (N,), got "
                f"{np.shape(self.start_m)}, {np.shape(self.end_m)}, {np.shape(self.radius_m)}"
            )
        object.__setattr__(self, "start_m", _as_points(start, n, "CapsuleSet.start_m"))
        object.__setattr__(self, "end_m", _as_points(self.end_m, n, "CapsuleSet.end_m"))
        radius = np.asarray(self.radius_m, dtype=float)
        if not np.all(np.isfinite(radius)) or np.any(radius < 0.0):
            raise ValueError(f"CapsuleSet.radius_m must be finite and >= 0, got {radius.tolist()}")
        object.__setattr__(self, "radius_m", radius)
        names = tuple(self.names) if self.names else tuple(f"capsule_{i}" for i in range(n))
        if len(names) != n:
            raise ValueError(f"CapsuleSet has {n} capsules but {len(names)} names")
        object.__setattr__(self, "names", names)

    def __len__(self) -> int:
        return len(self.radius_m)

    @classmethod
    def from_list(cls, capsules: Sequence[Tuple[Sequence[float], Sequence[float], float, str]]) -> "CapsuleSet":
        """From (start, end, radius, name) tuples."""
        if not capsules:
            return cls.empty()
        start, end, radius, names = zip(*capsules)
        return cls(np.array(start, dtype=float), np.array(end, dtype=float), np.array(radius, dtype=float), names)

    @classmethod
    def empty(cls) -> "CapsuleSet":
        return cls(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), ())

    def __add__(self, other: "CapsuleSet") -> "CapsuleSet":
        return CapsuleSet(
            np.concatenate([self.start_m, other.start_m]),
            np.concatenate([self.end_m, other.end_m]),
            np.concatenate([self.radius_m, other.radius_m]),
            self.names + other.names,
        )

    def transformed(self, pose: np.ndarray) -> "CapsuleSet":
        """The capsules moved by a 4x4 rigid transform (e.g. map frame -> arm base frame)."""
        rot, trans = pose[:3, :3], pose[:3, 3]
        return CapsuleSet(self.start_m @ rot.T + trans, self.end_m @ rot.T + trans, self.radius_m, self.names)


def segment_segment_distance(p1, q1, p2, q2) -> np.ndarray:
    """Distance between segments p1-q1 and p2-q2 (arrays (..., 3), broadcast) [m]."""
    d1, d2 = q1 - p1, q2 - p2
    r = p1 - p2
    a = np.einsum("...i,...i->...", d1, d1)
    e = np.einsum("...i,...i->...", d2, d2)
    f = np.einsum("...i,...i->...", d2, r)
    c = np.einsum("...i,...i->...", d1, r)
    b = np.einsum("...i,...i->...", d1, d2)
    a_ok, e_ok = a > _EPS, e > _EPS
    a_safe, e_safe = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    skew = denom > _EPS * np.maximum(a * e, _EPS)              # not parallel
    s = np.where(skew, np.clip((b * f - c * e) / np.where(skew, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / e_safe
    s = np.where(t < 0.0, np.clip(-c / a_safe, 0.0, 1.0), np.where(t > 1.0, np.clip((b - c) / a_safe, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # Degenerate segments (points).
    s = np.where(a_ok, s, 0.0)
    t = np.where(a_ok, t, np.clip(f / e_safe, 0.0, 1.0))
    t = np.where(e_ok, t, 0.0)
    s = np.where(e_ok | ~a_ok, s, np.clip(-c / a_safe, 0.0, 1.0))
    diff = (p1 + d1 * s[..., None]) - (p2 + d2 * t[..., None])
    return np.sqrt(np.einsum("...i,...i->...", diff, diff))


def point_segment_distance(x, p, q) -> np.ndarray:
    """Distance from points x to segments p-q (broadcast) [m]."""
    d = q - p
    dd = np.einsum("...i,...i->...", d, d)
    t = np.clip(np.einsum("...i,...i->...", x - p, d) / np.where(dd > _EPS, dd, 1.0), 0.0, 1.0)
    diff = x - (p + d * t[..., None])
    return np.sqrt(np.einsum("...i,...i->...", diff, diff))
