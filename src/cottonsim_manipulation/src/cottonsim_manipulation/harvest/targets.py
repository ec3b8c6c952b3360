"""Fusion of 3-D boll detections over frames into boll targets (map frame, metres).

Each frame's detections (a boll's centre as localised from the depth cloud,
with a 1-sigma position uncertainty) are associated with the existing targets:

* a pair is a candidate when the distance d between the detection and the
  target is within the gate: ``gate_sigma`` combined standard deviations,
  gate_sigma * sqrt(sigma_detection^2 + sigma_target^2), but at least
  ``min_gate_m`` and at most ``max_gate_m``. Distinct bolls (4-6 cm wide) have
  centres at least ~4 cm apart, so anything within 2.5 cm of a target is that
  boll whatever the sigmas claim, and nothing beyond 5 cm is;
* each detection goes to at most one target and each target takes at most one
  detection per frame (two bolls seen in one frame never merge, however
  close), the pairs chosen to minimise the sum of squared normalised
  distances (an optimal assignment, so an early, noisy pair of close
  targets does not swap its detections);
* an associated detection updates its target's position by the inverse-variance
  weighted running mean (sigma_target^2 = 1 / sum of 1 / sigma_detection^2);
  with ``track_observations`` N > 0 the target's weight before an update is
  capped at N - 1 times the new detection's, so the mean forgets old
  detections (an exponential window of about N) and follows a source that
  moves slowly in the fixed frame, as a boll does when the odometry drifts;
* a detection associated with no target starts a new one, unless it lies
  within ``picked_radius_m`` of a picked boll (a picked boll is never added
  again, even if a detection of its empty place comes in);
* but a picked target seen there again in ``reopen_observations`` frames more
  than ``reopen_after_s`` after its pick is open again, at the mean of those
  detections: the nozzle took another boll on its way in (two bolls of one
  node 2.7 cm apart), and the target's own boll still hangs there. The boll
  the nozzle carries away is out of the radius within a fraction of a second.

Targets are never dropped when they leave the view. A target is 'tentative'
until it has ``confirm_observations`` detections, then 'confirmed'; the
harvest marks it 'picked', or after ``max_attempts`` failed picks 'abandoned'.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

TENTATIVE, CONFIRMED, PICKED, ABANDONED = "tentative", "confirmed", "picked", "abandoned"
_NOT_GATED = 1e12


@dataclass(frozen=True)
class TargetFusionConfig:
    """gate_sigma: association gate in combined standard deviations (3-D errors: 4 keeps
        99.9 % of a boll's own detections, 3 only 97 %).
    max_gate_m: largest detection-to-target distance ever associated [m].
    min_sigma_m: floor on a detection's 1-sigma uncertainty [m].
    confirm_observations: detections after which a target is confirmed.
    picked_radius_m: detections this close to a picked boll are ignored [m].
    max_attempts: failed picks after which a target is abandoned (the harvester counts the arm's failures only).
    track_observations: 0: the mean keeps every detection; N > 0: it follows about the last N (module docstring).
    reopen_observations: frames that see a picked target again (within picked_radius_m, reopen_after_s after
        its pick) before it is open again (0: never).
    reopen_after_s: detections this soon after a pick do not reopen its target [s]."""

    gate_sigma: float = 5.0
    min_gate_m: float = 0.025
    max_gate_m: float = 0.05
    min_sigma_m: float = 0.002
    confirm_observations: int = 2
    picked_radius_m: float = 0.03
    max_attempts: int = 2
    track_observations: int = 0
    reopen_observations: int = 3
    reopen_after_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("gate_sigma", "min_gate_m", "max_gate_m", "min_sigma_m", "picked_radius_m", "reopen_after_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0.0 < value < 10.0):
                raise ValueError(f"TargetFusionConfig.{name} must be a number in (0, 10), got {value!r}")
        if self.min_gate_m > self.max_gate_m:
            raise ValueError(f"TargetFusionConfig.min_gate_m {self.min_gate_m} exceeds max_gate_m {self.max_gate_m}")
        for name in ("confirm_observations", "max_attempts", "track_observations", "reopen_observations"):
            value, low = getattr(self, name), 0 if name in ("track_observations", "reopen_observations") else 1
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not (low <= value <= 1000):
                raise ValueError(f"TargetFusionConfig.{name} must be an integer in [{low}, 1000], got {value!r}")


@dataclass(frozen=True)
class BollDetection3D:
    """A boll's centre seen in one frame: position_m (3,) in the map frame, sigma_m its 1-sigma error [m]."""

    position_m: np.ndarray
    sigma_m: float

    def __post_init__(self) -> None:
        pos = np.asarray(self.position_m, dtype=float).reshape(-1)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise ValueError(f"a boll detection's position must be 3 finite numbers [m], got {self.position_m!r}")
        if isinstance(self.sigma_m, bool) or not isinstance(self.sigma_m, (int, float)) or \
                not (math.isfinite(self.sigma_m) and self.sigma_m > 0.0):
            raise ValueError(f"a boll detection's sigma_m must be a positive number [m], got {self.sigma_m!r}")
        object.__setattr__(self, "position_m", pos)


@dataclass
class BollTarget:
    """One boll as the robot knows it (map frame)."""

    target_id: int
    position_m: np.ndarray
    sigma_m: float
    observations: int
    first_seen_s: float
    last_seen_s: float
    state: str = TENTATIVE
    attempts: int = 0
    _weight: float = field(default=0.0, repr=False)
    _picked_s: float = field(default=-math.inf, repr=False)      # the stamp of its pick
    _reseen: Dict[float, np.ndarray] = field(default_factory=dict, repr=False)   # stamp -> detection, after the pick


class TargetFusion:
    """Keeps the boll targets of a run; see the module docstring for the rules."""

    def __init__(self, config: Optional[TargetFusionConfig] = None):
        self.config = config or TargetFusionConfig()
        self._targets: Dict[int, BollTarget] = {}
        self._next_id = 0

    # ------------------------------------------------------------------ queries
    def targets(self, states: Sequence[str] = (TENTATIVE, CONFIRMED, PICKED, ABANDONED)) -> List[BollTarget]:
        """Targets in the given states, by id."""
        return [t for t in self._targets.values() if t.state in states]

    def open_targets(self) -> List[BollTarget]:
        """Confirmed targets still to pick."""
        return self.targets((CONFIRMED,))

    def target(self, target_id: int) -> BollTarget:
        if target_id not in self._targets:
            raise KeyError(f"no boll target {target_id}")
        return self._targets[target_id]

    def __len__(self) -> int:
        return len(self._targets)

    # ------------------------------------------------------------------ updates
    def update(self, detections: Sequence[BollDetection3D], stamp_s: float) -> List[int]:
        """Fuse one frame's detections; returns the target id of each detection
        (-1: ignored, near a picked boll)."""
        if not (isinstance(stamp_s, (int, float)) and math.isfinite(stamp_s)):
            raise ValueError(f"stamp_s must be a finite time [s], got {stamp_s!r}")
        for d in detections:
            if not isinstance(d, BollDetection3D):
                raise ValueError(f"detections must be BollDetection3D, got {type(d).__name__}")
        cfg = self.config
        result = [-1] * len(detections)
        if not detections:
            return result
        pos = np.array([d.position_m for d in detections])
        sig = np.maximum(np.array([d.sigma_m for d in detections]), cfg.min_sigma_m)
        active = [t for t in self._targets.values() if t.state != PICKED]
        if active:              # only targets within the largest gate of the detections' bounding box can pair
            tpos = np.array([t.position_m for t in active])
            near = np.all((tpos >= pos.min(axis=0) - cfg.max_gate_m) & (tpos <= pos.max(axis=0) + cfg.max_gate_m),
                          axis=1)
            active = [t for t, keep in zip(active, near) if keep]
        assigned = np.zeros(len(detections), dtype=bool)
        if active:
            tpos = np.array([t.position_m for t in active])
            tsig = np.array([t.sigma_m for t in active])
            dist = np.linalg.norm(pos[:, None, :] - tpos[None, :, :], axis=2)
            combined = np.sqrt(sig[:, None] ** 2 + tsig[None, :] ** 2)
            norm = dist / combined
            gated = dist <= np.clip(cfg.gate_sigma * combined, cfg.min_gate_m, cfg.max_gate_m)
            # Optimal assignment: least sum of squared normalised distances over gated pairs, solved over
            # the detections and targets that have a gated pair at all (the same assignment: any other
            # pair costs _NOT_GATED; a run's targets far from this frame's detections drop out).
            rows, cols = np.flatnonzero(gated.any(axis=1)), np.flatnonzero(gated.any(axis=0))
            cost = np.where(gated[np.ix_(rows, cols)], norm[np.ix_(rows, cols)] ** 2, _NOT_GATED)
            for i, j in zip(*linear_sum_assignment(cost)):
                d, t = rows[i], cols[j]
                if gated[d, t]:
                    assigned[d] = True
                    self._absorb(active[t], pos[d], sig[d], stamp_s)
                    result[d] = active[t].target_id
        picked = [t for t in self._targets.values() if t.state == PICKED]
        picked_pos = np.array([t.position_m for t in picked]).reshape(-1, 3)
        for d in np.flatnonzero(~assigned):
            if len(picked):
                distance = np.linalg.norm(picked_pos - pos[d], axis=1)
                nearest = int(np.argmin(distance))
                if distance[nearest] <= cfg.picked_radius_m:
                    if self._seen_again(picked[nearest], pos[d], sig[d], stamp_s):
                        result[d] = picked[nearest].target_id
                    continue
            result[d] = self._create(pos[d], sig[d], stamp_s)
        return result

    def mark_picked(self, target_id: int, stamp_s: float = -math.inf) -> None:
        """The boll is in the bin (at stamp_s, the detections' clock [s]): not picked, nor added, again, unless
        it is seen again (reopen_observations)."""
        target = self.target(target_id)
        target.state = PICKED
        target._picked_s = float(stamp_s)
        target._reseen = {}

    def _seen_again(self, target: BollTarget, position: np.ndarray, sigma: float, stamp_s: float) -> bool:
        """A detection near a picked target; reopens it (True) after reopen_observations frames (module docstring)."""
        cfg = self.config
        if not cfg.reopen_observations or stamp_s < target._picked_s + cfg.reopen_after_s:
            return False
        target._reseen.setdefault(float(stamp_s), position.copy())
        if len(target._reseen) < cfg.reopen_observations:
            return False
        seen = np.array(list(target._reseen.values()))
        w = 1.0 / (sigma * sigma)
        target.position_m = seen.mean(axis=0)
        target._weight = w * len(seen)
        target.sigma_m = 1.0 / math.sqrt(target._weight)
        target.observations += len(seen)
        target.last_seen_s = max(target.last_seen_s, stamp_s)
        target.state = CONFIRMED
        target._reseen = {}
        return True

    def mark_failed(self, target_id: int) -> str:
        """A pick of the target failed; returns its new state (abandoned after max_attempts)."""
        target = self.target(target_id)
        if target.state == PICKED:
            raise ValueError(f"boll target {target_id} is already picked")
        target.attempts += 1
        if target.attempts >= self.config.max_attempts:
            target.state = ABANDONED
        return target.state

    def _absorb(self, target: BollTarget, position: np.ndarray, sigma: float, stamp_s: float) -> None:
        w = 1.0 / (sigma * sigma)
        if self.config.track_observations:
            target._weight = min(target._weight, (self.config.track_observations - 1) * w)
        total = target._weight + w
        target.position_m = (target.position_m * target._weight + position * w) / total
        target._weight = total
        target.sigma_m = 1.0 / math.sqrt(total)
        target.observations += 1
        target.last_seen_s = max(target.last_seen_s, stamp_s)
        if target.state == TENTATIVE and target.observations >= self.config.confirm_observations:
            target.state = CONFIRMED

    def _create(self, position: np.ndarray, sigma: float, stamp_s: float) -> int:
        target_id = self._next_id
        self._next_id += 1
        target = BollTarget(target_id, position.copy(), float(sigma), 1, stamp_s, stamp_s,
                            CONFIRMED if self.config.confirm_observations <= 1 else TENTATIVE, 0,
                            1.0 / (sigma * sigma))
        self._targets[target_id] = target
        return target_id
