"""The planar pose (x [m], y [m], yaw [rad]) and its algebra, shared by every package.

A :class:`Pose2D` is a position and a heading (counter-clockwise from +x,
REP-103) in some fixed frame. ``compose(a, b)`` places pose b, given in the
frame of pose a, into a's parent frame; ``world_to_frame`` / ``frame_to_world``
convert coordinate arrays between a parent frame and a frame given as a pose in
it (e.g. the world and the robot's 'Home' spawn frame).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cottonsim_common.angles import wrap_angle


@dataclass(frozen=True)
class Pose2D:
    """A planar pose: position [m] and heading [rad]; every field must be a finite number."""

    x_m: float
    y_m: float
    yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "yaw_rad"):
            value = getattr(self, name)
            try:
                ok = math.isfinite(float(value))
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(f"Pose2D.{name} must be a finite number, got {value!r}")

    def as_array(self) -> np.ndarray:
        return np.array([self.x_m, self.y_m, self.yaw_rad], dtype=float)


def as_pose(p) -> Pose2D:
    """Any object with x_m/y_m/yaw_rad (or a 2- or 3-sequence) -> Pose2D (validated)."""
    if isinstance(p, Pose2D):
        return p
    if hasattr(p, "x_m") and hasattr(p, "y_m"):
        return Pose2D(float(p.x_m), float(p.y_m), float(getattr(p, "yaw_rad", 0.0)))
    seq = list(p)
    if len(seq) not in (2, 3):
        raise ValueError(f"a pose needs (x, y[, yaw]), got {len(seq)} values")
    return Pose2D(float(seq[0]), float(seq[1]), float(seq[2]) if len(seq) == 3 else 0.0)


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """a (+) b: pose b given in frame a, expressed in a's parent frame."""
    c, s = math.cos(a.yaw_rad), math.sin(a.yaw_rad)
    return Pose2D(a.x_m + c * b.x_m - s * b.y_m, a.y_m + s * b.x_m + c * b.y_m,
                  wrap_angle(a.yaw_rad + b.yaw_rad))


def inverse(a: Pose2D) -> Pose2D:
    """The pose p with compose(a, p) == identity."""
    c, s = math.cos(a.yaw_rad), math.sin(a.yaw_rad)
    return Pose2D(-c * a.x_m - s * a.y_m, s * a.x_m - c * a.y_m, wrap_angle(-a.yaw_rad))


def transform_points(pose: Pose2D, points: np.ndarray) -> np.ndarray:
    """(N, 2) points in the pose's frame -> parent frame."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    xw, yw = frame_to_world(pose, pts[:, 0], pts[:, 1])
    return np.stack([xw, yw], axis=1)


def world_to_frame(frame: Pose2D, x_m, y_m, yaw_rad=None):
    """Parent-frame coordinates -> coordinates in ``frame`` (a pose given in the parent).

    Returns (x, y), or (x, y, yaw) when yaw_rad is given (yaw wrapped into [-pi, pi)).
    """
    c, s = math.cos(frame.yaw_rad), math.sin(frame.yaw_rad)
    dx, dy = np.asarray(x_m, float) - frame.x_m, np.asarray(y_m, float) - frame.y_m
    xf, yf = c * dx + s * dy, -s * dx + c * dy
    if yaw_rad is None:
        return xf, yf
    return xf, yf, wrap_angle(np.asarray(yaw_rad, float) - frame.yaw_rad)


def frame_to_world(frame: Pose2D, x_m, y_m, yaw_rad=None):
    """Coordinates in ``frame`` -> parent frame (inverse of :func:`world_to_frame`)."""
    c, s = math.cos(frame.yaw_rad), math.sin(frame.yaw_rad)
    x, y = np.asarray(x_m, float), np.asarray(y_m, float)
    xw, yw = frame.x_m + c * x - s * y, frame.y_m + s * x + c * y
    if yaw_rad is None:
        return xw, yw
    return xw, yw, wrap_angle(np.asarray(yaw_rad, float) + frame.yaw_rad)
