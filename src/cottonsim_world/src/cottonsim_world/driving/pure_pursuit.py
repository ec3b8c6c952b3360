"""A pure-pursuit path follower: the simulator's own baseline driver.

It drives a polyline (e.g. the farm's default serpentine route) from the
robot's *estimated* pose, never from ground truth, so that a headless demo
drive exercises the same odometry a navigation stack would get. The full
navigation stack (move_base with navfn + DWA) lives in cottonsim_navigation;
this follower is what the simulator ships so the robot can drive before and
without it.

Algorithm: keep a progress index along the path that only moves forward
(so the follower never jumps to a neighbouring lane of a serpentine), pick
the path point one look-ahead distance ahead of the robot's projection,
steer along the circular arc through it (curvature = 2 sin(alpha) / L),
and turn in place first when that point lies far off the heading.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from cottonsim_common.validation import require_fields


@dataclass(frozen=True)
class PurePursuitConfig:
    lookahead_m: float = 0.8              # distance to the pursued path point [m]
    cruise_speed_m_s: float = 0.5         # forward speed on straight path [m/s] (paper: 1.8 km/h)
    max_angular_rad_s: float = 1.0        # angular speed cap [rad/s]
    turn_in_place_rad: float = 1.0        # heading error above which the robot turns on the spot [rad]
    goal_tolerance_m: float = 0.15        # distance to the final point that ends the drive [m]
    search_window_m: float = 2.0          # how far ahead of the progress index projection searches [m]

    def __post_init__(self):
        require_fields(self, "PurePursuitConfig.",
                       positive=("lookahead_m", "cruise_speed_m_s", "max_angular_rad_s", "turn_in_place_rad",
                                 "goal_tolerance_m", "search_window_m"))


def densify(points_xy: np.ndarray, spacing_m: float = 0.05) -> np.ndarray:
    """Resample a polyline so consecutive points are at most spacing_m apart."""
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    if len(pts) < 2:
        raise ValueError("a path needs at least two points")
    out = [pts[0]]
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, int(math.ceil(np.linalg.norm(b - a) / spacing_m)))
        for k in range(1, n + 1):
            out.append(a + (b - a) * (k / n))
    return np.array(out)


class PurePursuit:
    """Follows a polyline given in the frame of the poses fed to ``command``."""

    def __init__(self, path_xy: np.ndarray, config: PurePursuitConfig = PurePursuitConfig()):
        self.config = config
        self.path = densify(path_xy)
        self._arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(self.path, axis=0), axis=1))])
        self._index = 0
        self.done = False

    @property
    def progress_m(self) -> float:
        """Arc length of the path covered so far [m]."""
        return float(self._arc[self._index])

    @property
    def length_m(self) -> float:
        return float(self._arc[-1])

    def command(self, x_m: float, y_m: float, yaw_rad: float) -> Tuple[float, float]:
        """(linear_x [m/s], angular_z [rad/s]) for the robot at the given pose."""
        if not all(math.isfinite(v) for v in (x_m, y_m, yaw_rad)):
            return 0.0, 0.0
        cfg = self.config
        here = np.array([x_m, y_m])
        if np.linalg.norm(self.path[-1] - here) < cfg.goal_tolerance_m and \
                self._arc[-1] - self._arc[self._index] < cfg.search_window_m:
            self.done = True
        if self.done:
            return 0.0, 0.0
        # Advance the progress index to the nearest point within the search window ahead.
        window_end = np.searchsorted(self._arc, self._arc[self._index] + cfg.search_window_m, side="right")
        window = self.path[self._index:window_end]
        self._index += int(np.argmin(np.linalg.norm(window - here, axis=1)))
        # Look-ahead point: first point at least lookahead_m away along the path.
        target_arc = self._arc[self._index] + cfg.lookahead_m
        j = min(int(np.searchsorted(self._arc, target_arc)), len(self.path) - 1)
        dx, dy = self.path[j] - here
        alpha = math.atan2(dy, dx) - yaw_rad
        alpha = (alpha + math.pi) % (2.0 * math.pi) - math.pi
        if abs(alpha) > cfg.turn_in_place_rad:
            return 0.0, math.copysign(cfg.max_angular_rad_s, alpha)
        distance = max(math.hypot(dx, dy), 1e-6)
        curvature = 2.0 * math.sin(alpha) / distance
        v = cfg.cruise_speed_m_s
        w = v * curvature
        if abs(w) > cfg.max_angular_rad_s:
            v *= cfg.max_angular_rad_s / abs(w)
            w = math.copysign(cfg.max_angular_rad_s, w)
        return v, w
