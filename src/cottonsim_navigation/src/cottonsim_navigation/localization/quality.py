"""Is AMCL localised? A yes/no signal from the particle spread and the scan fit.

Why: a waypoint navigator must not drive on a pose estimate that is wrong
(after a kidnap, a bad initial pose, or while the filter is still spread out
after global localisation). Neither of AMCL's own outputs says so alone: the
covariance of the heaviest cluster can be small around a wrong pose (a tight
wrong /initialpose), and a good scan fit can come from a pose one crop row off
while the particles are still spread over several rows. So the signal asks
for both:

* spread: the whole particle set (not only the best cluster) has a position
  standard deviation (square root of the largest eigenvalue of the x-y
  covariance) <= ``max_std_xy_m`` and a heading standard deviation
  <= ``max_std_yaw_rad``;
* fit: of the beams the laser model uses, at least ``min_hit_fraction`` end
  within ``hit_distance_m`` of an occupied map cell when the robot stands at
  the estimate (beams ending beyond the map count as misses).

To avoid flicker, the state changes only after ``switch_after`` consecutive
filter updates that agree on the new state (hysteresis); a re-initialisation
(:meth:`LocalizationMonitor.reset`) makes it "not localised" at once.

Kidnap detection: a tight particle set whose scan fit stays poor for
``relocalize_after`` consecutive updates is confidently wrong (the robot was
moved). Poor here is judged per beam, on the beams the map can judge: a beam
*contradicts* the estimate when its end point lies in mapped free space farther
than ``hit_distance_m`` from any obstacle (or, with the free-space check, it
would have crossed ``max_crossed_m`` of mapped obstacle); a beam ending in an
unknown cell or beyond the map says nothing. The fit is poor when the share of
the judged beams that hit is below ``min_hit_fraction`` (:func:`scan_fit`). So
a robot in the open headland whose scan sees little, or beams into unmapped
parts, are no kidnap, where the plain hit fraction over all beams (which the
"localised" verdict uses: it needs positive evidence) would be low. :attr:`LocalizationMonitor.kidnapped`
then turns true and the caller should spread the particles again
(``relocalize_std_xy_m`` / ``relocalize_std_yaw_rad`` around the estimate, or
globally). This complements AMCL's random-particle recovery (alpha_slow /
alpha_fast), which on a 1.8 m-periodic farm needs many updates to hit the true
pose by chance.

Standing still: AMCL updates only after the robot moved, but a kidnapped
robot may stand (the navigator stops it while AMCL is not localised). The
:class:`StationaryUpdatePolicy` asks for filter updates without motion, at
most every ``stationary_update_period_s``: while localised when the scan does
not fit the map at the current estimate (so a kidnap of a standing robot is
noticed), and while re-localising after a kidnap (then the particles are
roughened first, see ``ParticleFilter.roughen``, so repeated updates on the
scans of a standing robot do not collapse the set).

Reported covariance: while not localised, :func:`reported_covariance` widens
the pose covariance a node publishes to that of the whole particle set, and,
while the scan does not fit the map at the estimate, to at least the
re-spread covariance: a re-localising set can agree on a wrong pose (0.66 m
along the heading in front of the rows, seen in the kidnap rostest) before
the scan fit rejects it, and its own spread would then look trustworthy.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional

import numpy as np

from cottonsim_common.validation import require_fields, require_instance, require_int
from .particle_filter import mean_resultant_length
from .sensor_models import LikelihoodField, Scan

if TYPE_CHECKING:
    from .amcl import Amcl


@dataclass(frozen=True)
class LocalizationQualityConfig:
    """Thresholds of the localised signal.

    max_std_xy_m [m]: largest position std dev of the particle set (default 0.15);
    max_std_yaw_rad [rad]: largest heading std dev (default 0.1, ~6 deg);
    hit_distance_m [m]: a beam "hits" when its end point is this close to an obstacle (default 0.2,
        one sigma_hit of the laser model);
    min_hit_fraction: share of used beams that must hit (0..1, default 0.6);
    switch_after: consecutive filter updates that must agree before the state changes (>= 1, default 2);
    relocalize_after: consecutive tight-but-poor-fit updates that count as a kidnap (>= 0, 0 = never; default 3);
    relocalize_std_xy_m [m], relocalize_std_yaw_rad [rad]: spread of the particles re-drawn around the
        estimate after a kidnap (defaults 2.0 m, 0.3 rad); relocalize_std_xy_m is the spread along the
        estimate's heading;
    relocalize_std_across_m [m]: the spread across the estimate's heading; 0 (default) = the same as
        relocalize_std_xy_m (a round spread). In a row crop farm driven along the rows, a smaller value keeps
        the re-drawn set in the lane it was in: the lanes (1.8 m apart) look alike to the laser, so a
        round 2 m spread lets the standing filter settle on a neighbouring lane (a kidnap across the rows
        is not recoverable from the scan either way; see docs/map_experiment.md, "Kidnap");
    relocalize_round_fraction: share (0..1) of the re-drawn particles that get the round spread
        (relocalize_std_xy_m in every direction) instead; default 0. Offline (docs/map_experiment.md)
        0.5 with relocalize_std_across_m 0.5 recovered 8/10 kidnaps toward the rows (10/10 without) and
        6/10 across them near the farm's edge (0/10 without);
    max_crossed_m [m]: with the free-space check, a beam that crosses this much mapped obstacle on its way
        is a miss too (default 0.5; measured in front of the rows: ~10-15 % of the true pose's beams,
        50-70 % of a pose 3 m closer to the rows);
    stationary_update_period_s [s]: the shortest interval between filter updates asked for while the
        robot stands (see StationaryUpdatePolicy); 0 = never (ROS amcl's behaviour); default 0.5;
    roughen_std_xy_m [m], roughen_std_yaw_rad [rad]: jitter added to the particles before each such
        update while re-localising (defaults 0.03 m, 0.01 rad);
    relocalize_particles: how many particles the re-spread after a kidnap draws (default 10000; 0 = AMCL's
        max_particles). The scan's likelihood has narrow peaks (~0.1 m, ~0.02 rad), and in the farm some
        wrong poses further along a lane are peaks only a few nats below the true one; 2000 particles over
        a 2 m re-spread put ~0.2 particles on a peak, so the first update's resampling collapses the set on
        whichever peak one happened to hit. Drawn densely, the true peak is sampled and wins; the first
        resampling brings the set back to at most max_particles (docs/map_experiment.md, "Kidnap").
    """

    max_std_xy_m: float = 0.15
    max_std_yaw_rad: float = 0.1
    hit_distance_m: float = 0.2
    min_hit_fraction: float = 0.6
    switch_after: int = 2
    relocalize_after: int = 3
    relocalize_std_xy_m: float = 2.0
    relocalize_std_yaw_rad: float = 0.3
    relocalize_std_across_m: float = 0.0
    relocalize_round_fraction: float = 0.0
    max_crossed_m: float = 0.5
    stationary_update_period_s: float = 0.5
    roughen_std_xy_m: float = 0.03
    roughen_std_yaw_rad: float = 0.01
    relocalize_particles: int = 10000

    def __post_init__(self) -> None:
        require_fields(self, positive=("max_std_xy_m", "max_std_yaw_rad", "hit_distance_m", "relocalize_std_xy_m",
                                       "relocalize_std_yaw_rad", "max_crossed_m"),
                       non_negative=("stationary_update_period_s", "roughen_std_xy_m", "roughen_std_yaw_rad",
                                     "relocalize_std_across_m"),
                       fractions=("min_hit_fraction", "relocalize_round_fraction"))
        require_int("switch_after", self.switch_after, 1)
        require_int("relocalize_particles", self.relocalize_particles, 0)
        require_int("relocalize_after", self.relocalize_after, 0)

    def relocalize_covariance(self, yaw_rad: float = 0.0) -> np.ndarray:
        """3x3 covariance (x, y, yaw) of the re-spread after a kidnap [m^2, rad^2], the estimate's heading
        being ``yaw_rad``: relocalize_std_xy_m along it, relocalize_std_across_m (0: the same) across it."""
        if isinstance(yaw_rad, bool) or not isinstance(yaw_rad, (int, float)) or not math.isfinite(yaw_rad):
            raise ValueError(f"yaw_rad must be a finite number, got {yaw_rad!r}")
        along = self.relocalize_std_xy_m
        across = self.relocalize_std_across_m if self.relocalize_std_across_m > 0 else along
        c, s = math.cos(yaw_rad), math.sin(yaw_rad)
        rot = np.array([[c, -s], [s, c]])
        cov = np.zeros((3, 3))
        cov[:2, :2] = rot @ np.diag([along ** 2, across ** 2]) @ rot.T
        cov[2, 2] = self.relocalize_std_yaw_rad ** 2
        return cov


def respread_after_kidnap(amcl: "Amcl", pose, config: LocalizationQualityConfig) -> None:
    """Re-draw AMCL's particles around ``pose`` (x_m, y_m, yaw_rad; the wrong estimate) after a detected
    kidnap: ``relocalize_particles`` of them (0: max_particles) with :meth:`~LocalizationQualityConfig.
    relocalize_covariance` along / across the pose's heading, ``relocalize_round_fraction`` of them then
    re-drawn with the round spread (relocalize_std_xy_m every way)."""
    x, y, yaw = (float(v) for v in pose)
    amcl.initialise((x, y, yaw), config.relocalize_covariance(yaw), config.relocalize_particles or None)
    if config.relocalize_round_fraction > 0:
        round_cov = dataclasses.replace(config, relocalize_std_across_m=0.0).relocalize_covariance()
        amcl.filter.redraw_fraction((x, y, yaw), round_cov, config.relocalize_round_fraction)


def particle_spread(particles: np.ndarray, weights: Optional[np.ndarray] = None):
    """(std_xy_m, std_yaw_rad) of a weighted particle set (N, 3).

    std_xy_m is the square root of the largest eigenvalue of the weighted x-y
    covariance; std_yaw_rad is the circular standard deviation sqrt(-2 ln R).
    """
    p = np.asarray(particles, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError(f"particles must be a non-empty (N, 3) array, got shape {p.shape}")
    if weights is None:
        w = np.full(p.shape[0], 1.0 / p.shape[0])
    else:
        w = np.asarray(weights, dtype=float).reshape(-1)
        if w.shape[0] != p.shape[0] or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
            raise ValueError("weights must be N finite values >= 0 with a positive sum")
        w = w / w.sum()
    mx, my = float(w @ p[:, 0]), float(w @ p[:, 1])
    dx, dy = p[:, 0] - mx, p[:, 1] - my
    cxx, cyy, cxy = float(w @ (dx * dx)), float(w @ (dy * dy)), float(w @ (dx * dy))
    # largest eigenvalue of [[cxx, cxy], [cxy, cyy]]
    lam = 0.5 * (cxx + cyy) + math.sqrt(max(0.25 * (cxx - cyy) ** 2 + cxy * cxy, 0.0))
    r = mean_resultant_length(p[:, 2], w)
    std_yaw = math.sqrt(-2.0 * math.log(r)) if r > 1e-12 else math.pi
    return math.sqrt(max(lam, 0.0)), std_yaw


def scan_hit_fraction(field: LikelihoodField, pose, scan: Scan, hit_distance_m: float,
                      max_crossed_m: Optional[float] = None) -> float:
    """Share of the model's beams that hit (see :func:`scan_fit`; beams ending beyond the map count as
    misses); 0.0 when no beam is usable."""
    return scan_fit(field, pose, scan, hit_distance_m, max_crossed_m)[0]


def scan_fit(field: LikelihoodField, pose, scan: Scan, hit_distance_m: float,
             max_crossed_m: Optional[float] = None):
    """(hit_fraction, judged_hit_fraction) of the model's beams with the robot at ``pose`` (x, y, yaw).

    A beam hits when its end point lies within ``hit_distance_m`` of an obstacle of ``field``'s map.
    hit_fraction: the share of all used beams that hit (0.0 when no beam is usable). judged_hit_fraction:
    the share among the beams the map can judge -- those that hit and those that contradict the pose
    (end point in a mapped cell, not a hit); NaN when there is none (see the module doc).

    With ``max_crossed_m`` and a field that has ``crossed_lengths`` (a FreeSpaceCheckedField), a beam
    that would have crossed that much mapped obstacle on its way is no hit and contradicts the pose: its
    end point may sit in a hedge, but the beam could not have got there (a pose metres along the rows).
    """
    pts = field.select_beams(scan)
    if pts.shape[0] == 0:
        return 0.0, math.nan
    x, y, yaw = (float(v) for v in np.asarray(pose, dtype=float).reshape(3))
    c, s = math.cos(yaw), math.sin(yaw)
    wx = x + c * pts[:, 0] - s * pts[:, 1]
    wy = y + s * pts[:, 0] + c * pts[:, 1]
    spec = field.spec
    mx = np.floor((wx - spec.origin_x_m) / spec.resolution_m).astype(np.int64)
    my = np.floor((wy - spec.origin_y_m) / spec.resolution_m).astype(np.int64)
    inside = (mx >= 0) & (mx < spec.width) & (my >= 0) & (my < spec.height)
    d = np.full(pts.shape[0], np.inf)
    d[inside] = field.distance_m[my[inside], mx[inside]]
    known = np.zeros(pts.shape[0], dtype=bool)
    known[inside] = field.known[my[inside], mx[inside]]
    hit = d <= hit_distance_m
    contradicts = known & ~hit
    if max_crossed_m is not None and hasattr(field, "crossed_lengths"):
        crossed = field.crossed_lengths((x, y, yaw), scan) >= max_crossed_m
        contradicts |= hit & crossed
        hit &= ~crossed
    judged = int(hit.sum() + contradicts.sum())
    return float(np.mean(hit)), (float(hit.sum()) / judged if judged else math.nan)


class LocalizationMonitor:
    """Hysteresis over (spread, fit) checks; :attr:`localized` is the current verdict."""

    def __init__(self, config: LocalizationQualityConfig = LocalizationQualityConfig()) -> None:
        require_instance("config", config, LocalizationQualityConfig)
        self.config = config
        self.localized = False
        self._streak = 0
        self.last_std_xy_m = math.inf
        self.last_std_yaw_rad = math.inf
        self.last_hit_fraction = 0.0
        self._poor_fit_streak = 0

    def reset(self) -> None:
        """The filter was re-initialised: not localised until the checks pass again."""
        self.localized = False
        self._streak = 0
        self._poor_fit_streak = 0

    @property
    def suspect(self) -> bool:
        """The last update had a tight set with a poor scan fit (a kidnap may be building up)."""
        return self._poor_fit_streak > 0

    @property
    def kidnapped(self) -> bool:
        """The set has been tight with a poor scan fit for ``relocalize_after`` updates (see module doc)."""
        n = self.config.relocalize_after
        return n > 0 and self._poor_fit_streak >= n

    def check(self, std_xy_m: float, std_yaw_rad: float, hit_fraction: float) -> bool:
        """One-update verdict without hysteresis."""
        c = self.config
        return bool(std_xy_m <= c.max_std_xy_m and std_yaw_rad <= c.max_std_yaw_rad
                    and hit_fraction >= c.min_hit_fraction)

    def update(self, std_xy_m: float, std_yaw_rad: float, hit_fraction: float,
               judged_hit_fraction: Optional[float] = None) -> bool:
        """Feed one filter update's numbers; returns the (possibly switched) state.

        judged_hit_fraction: :func:`scan_fit`'s second value (None: the same as hit_fraction; NaN: no
        beam could be judged, no evidence of a kidnap). A kidnap builds up only while both are poor."""
        self.last_std_xy_m, self.last_std_yaw_rad, self.last_hit_fraction = std_xy_m, std_yaw_rad, hit_fraction
        ok = self.check(std_xy_m, std_yaw_rad, hit_fraction)
        c = self.config
        tight = std_xy_m <= c.max_std_xy_m and std_yaw_rad <= c.max_std_yaw_rad
        judged = hit_fraction if judged_hit_fraction is None else judged_hit_fraction
        poor = hit_fraction < c.min_hit_fraction and judged < c.min_hit_fraction      # False for NaN
        self._poor_fit_streak = self._poor_fit_streak + 1 if (tight and poor) else 0
        if ok == self.localized:
            self._streak = 0
        else:
            self._streak += 1
            if self._streak >= self.config.switch_after:
                self.localized = ok
                self._streak = 0
        return self.localized


def set_covariance(particles: np.ndarray, weights: Optional[np.ndarray] = None) -> np.ndarray:
    """3x3 covariance (x, y, yaw) of the whole weighted set [m^2, rad^2]: the x-y block of all particles
    (not only the heaviest cluster) and the circular yaw variance -2 ln R; cross terms with yaw are 0."""
    p = np.asarray(particles, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError(f"particles must be a non-empty (N, 3) array, got shape {p.shape}")
    w = np.full(p.shape[0], 1.0 / p.shape[0]) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (p.shape[0],) or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be N finite values >= 0 with a positive sum")
    w = w / w.sum()
    d = p[:, :2] - w @ p[:, :2]
    cov = np.zeros((3, 3))
    cov[:2, :2] = (d * w[:, None]).T @ d
    r = mean_resultant_length(p[:, 2], w)
    cov[2, 2] = -2.0 * math.log(r) if r > 1e-12 else math.pi ** 2
    return cov


class StationaryUpdatePolicy:
    """When to run AMCL's filter although the robot has not moved (see the module docstring).

    Call :meth:`decide` for every scan; it returns ``(update, roughen)``. ``relocalizing`` is set by
    :meth:`start_relocalizing` (after a detected kidnap) and cleared once the monitor is localised again.
    """

    def __init__(self, config: LocalizationQualityConfig = LocalizationQualityConfig()) -> None:
        require_instance("config", config, LocalizationQualityConfig)
        self.config = config
        self.relocalizing = False
        self._last_s: Optional[float] = None

    def start_relocalizing(self) -> None:
        self.relocalizing = True

    def stop_relocalizing(self) -> None:
        self.relocalizing = False

    def due(self, now_s: float) -> bool:
        """The period since the last asked-for update has passed (sim time [s]; a jump back resets it)."""
        period = self.config.stationary_update_period_s
        if period <= 0 or not math.isfinite(now_s):
            return False
        return self._last_s is None or now_s < self._last_s or now_s - self._last_s >= period

    def decide(self, now_s: float, localized: bool, hit_fraction_now: Optional[float] = None,
               suspect: bool = False):
        """(update, roughen) for this scan.

        localized: the monitor's verdict; hit_fraction_now: the scan fit at the current estimate (only
        needed while localised; None = not computed, no update); suspect: the monitor suspects a kidnap
        (:attr:`LocalizationMonitor.suspect`): updates go on although the verdict already turned "not
        localised", until the kidnap is confirmed (and the set re-spread) or the fit recovers.
        """
        if localized:
            self.relocalizing = False
        if not self.due(now_s):
            return False, False
        if self.relocalizing:
            self._last_s = now_s
            return True, True
        if localized and hit_fraction_now is not None and hit_fraction_now < self.config.min_hit_fraction:
            self._last_s = now_s
            return True, False
        if suspect and not localized:
            self._last_s = now_s
            return True, False
        return False, False


def reported_covariance(filter_covariance: np.ndarray, particles: np.ndarray, weights: Optional[np.ndarray],
                        localized: bool, hit_fraction: float, yaw_rad: float,
                        config: LocalizationQualityConfig = LocalizationQualityConfig()) -> np.ndarray:
    """The 3x3 (x, y, yaw) covariance to publish with the pose estimate [m^2, rad^2].

    Localised: ``filter_covariance`` (AMCL's, of the heaviest cluster) as it is. Not localised: its x-y
    block is replaced by the whole set's (:func:`set_covariance` of ``particles`` / ``weights``) when that
    has the larger trace, and its yaw variance is at least the set's; if moreover the scan fit
    ``hit_fraction`` is below ``config.min_hit_fraction``, the x-y block and the yaw variance are at least
    those of ``config.relocalize_covariance(yaw_rad)`` (the estimate is unverified: see the module doc).
    """
    cov = np.array(filter_covariance, dtype=float)
    if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
        raise ValueError(f"filter_covariance must be a finite 3x3 array, got shape {cov.shape}")
    if localized:
        return cov
    if isinstance(hit_fraction, bool) or not isinstance(hit_fraction, (int, float)) \
            or not 0.0 <= hit_fraction <= 1.0:
        raise ValueError(f"hit_fraction must lie in [0, 1], got {hit_fraction!r}")
    floors = [set_covariance(particles, weights)]
    if hit_fraction < config.min_hit_fraction:
        floors.append(config.relocalize_covariance(yaw_rad))
    for floor in floors:
        if np.trace(floor[:2, :2]) > np.trace(cov[:2, :2]):
            cov[:2, :2] = floor[:2, :2]
        cov[2, 2] = max(cov[2, 2], floor[2, 2])
    return cov
