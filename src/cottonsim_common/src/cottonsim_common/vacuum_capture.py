"""The vacuum nozzle's capture rule: when does the nozzle take a boll?

Shared: the simulator's nozzle applies it, the robot-side approach planner aims inside it.

The simulation does not model air flow or the fibre's pull-off force; a boll
is captured when the nozzle tip is within ``capture_radius_m`` of the boll's
centre and the nozzle points into the boll: the angle between the nozzle axis
(out of the nozzle, tool0's z) and the boll's inward direction (minus its
outward direction, from the plant's stem to the boll) is at most
``cone_half_angle_rad``. A boll without an outward direction (on the stem
axis, a zero vector) accepts any nozzle direction.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Tuple

import numpy as np


@dataclass(frozen=True)
class CaptureConfig:
    """capture_radius_m: largest tip-to-boll-centre distance that captures [m] (a boll is 4-6 cm wide).
    cone_half_angle_rad: largest angle between the nozzle axis and the boll's inward direction [rad]."""

    capture_radius_m: float = 0.02
    cone_half_angle_rad: float = math.radians(45.0)

    def __post_init__(self) -> None:
        r = self.capture_radius_m
        if isinstance(r, bool) or not isinstance(r, (int, float)) or not (0.0 < r <= 0.5):
            raise ValueError(f"CaptureConfig.capture_radius_m must be in (0, 0.5] m, got {r!r}")
        a = self.cone_half_angle_rad
        if isinstance(a, bool) or not isinstance(a, (int, float)) or not (0.0 < a <= math.pi):
            raise ValueError(f"CaptureConfig.cone_half_angle_rad must be in (0, pi], got {a!r}")


@dataclass(frozen=True)
class CaptureCheck:
    """captured; reason 'captured', 'too_far' or 'misaligned'; the tip's distance [m] and the angle [rad]."""

    captured: bool
    reason: str
    distance_m: float
    angle_rad: float


def _vector(v, what: str) -> np.ndarray:
    arr = np.asarray(v, dtype=float).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} must be 3 finite numbers, got {v!r}")
    return arr


def nozzle_tip(flange_pose: np.ndarray, nozzle_length_m: float) -> Tuple[np.ndarray, np.ndarray]:
    """Tip position [m] and unit axis of a nozzle nozzle_length_m long on tool0 (pose 4x4, z out of the flange)."""
    t = np.asarray(flange_pose, dtype=float)
    if t.shape != (4, 4) or not np.all(np.isfinite(t)):
        raise ValueError("the flange pose must be a finite 4x4 matrix")
    if not (math.isfinite(nozzle_length_m) and nozzle_length_m >= 0.0):
        raise ValueError(f"nozzle_length_m must be >= 0, got {nozzle_length_m!r}")
    axis = t[:3, 2] / np.linalg.norm(t[:3, 2])
    return t[:3, 3] + nozzle_length_m * axis, axis


def _angles(axis: np.ndarray, outward: np.ndarray) -> np.ndarray:
    """Angle between the axis and -outward (0 where outward is zero) [rad]; outward (N, 3)."""
    norm = np.linalg.norm(outward, axis=-1)
    cos = -(outward @ axis) / np.where(norm > 1e-9, norm, 1.0)
    return np.where(norm > 1e-9, np.arccos(np.clip(cos, -1.0, 1.0)), 0.0)


def check_capture(tip_m, axis, boll_centre_m, boll_outward, config: CaptureConfig = CaptureConfig()) -> CaptureCheck:
    """Whether a nozzle with its tip at tip_m pointing along axis captures one boll."""
    tip = _vector(tip_m, "nozzle tip")
    ax = _vector(axis, "nozzle axis")
    if np.linalg.norm(ax) < 1e-9:
        raise ValueError("nozzle axis must not be zero")
    ax = ax / np.linalg.norm(ax)
    centre = _vector(boll_centre_m, "boll centre")
    out = _vector(boll_outward, "boll outward direction")
    distance = float(np.linalg.norm(tip - centre))
    angle = float(_angles(ax, out[None])[0])
    if distance > config.capture_radius_m:
        return CaptureCheck(False, "too_far", distance, angle)
    if angle > config.cone_half_angle_rad:
        return CaptureCheck(False, "misaligned", distance, angle)
    return CaptureCheck(True, "captured", distance, angle)


def find_capture(tip_m, axis, boll_centres_m, boll_outwards, config: CaptureConfig = CaptureConfig()) -> int:
    """Index of the boll the nozzle captures (the nearest that qualifies), or -1.

    boll_centres_m, boll_outwards: (N, 3) in the same frame as the tip and axis.
    """
    tip = _vector(tip_m, "nozzle tip")
    ax = _vector(axis, "nozzle axis")
    if np.linalg.norm(ax) < 1e-9:
        raise ValueError("nozzle axis must not be zero")
    ax = ax / np.linalg.norm(ax)
    centres = np.asarray(boll_centres_m, dtype=float).reshape(-1, 3)
    outwards = np.asarray(boll_outwards, dtype=float).reshape(-1, 3)
    if centres.shape != outwards.shape:
        raise ValueError(f"boll centres {centres.shape} and outward directions {outwards.shape} differ in number")
    if not (np.all(np.isfinite(centres)) and np.all(np.isfinite(outwards))):
        raise ValueError("boll centres or outward directions contain NaN or infinity")
    if not len(centres):
        return -1
    distance = np.linalg.norm(centres - tip, axis=1)
    ok = (distance <= config.capture_radius_m) & (_angles(ax, outwards) <= config.cone_half_angle_rad)
    if not ok.any():
        return -1
    return int(np.flatnonzero(ok)[np.argmin(distance[ok])])
