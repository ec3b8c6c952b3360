"""The AMCL node's policy around the filter: localised signal, kidnap -> re-spread, stationary updates.

Why a separate core: the amcl node and the offline benchmarks (kidnap, replay of a recorded drive) must
run the very same policy; here it is pure (no ROS), so both call :meth:`LocalizationSupervisor.step` with
one scan and the odometry at its time.

One :meth:`LocalizationSupervisor.step`:

1. switch the free-space check of the beams (``free_space_mode``) on or off for this update: "always",
   "relocalizing" = only while not localised, "off";
2. ask for a filter update without motion when the :class:`~.quality.StationaryUpdatePolicy` says so
   (while localised with a poor scan fit at the current estimate; while a kidnap is suspected; once
   localised, while "not localised" again and the robot stands -- the navigator stops it then, and
   without updates a fit that recovers would never be confirmed (while it drives, the motion updates do
   that: forced updates on top of them, without motion noise, over-tighten the set until a scan that
   fits a little worse looks like a kidnap); while re-localising after a kidnap, then roughening the
   particles first);
3. run :meth:`Amcl.update <.amcl.Amcl.update>`; after a filter update, feed the particle spread and the
   scan fit at the estimate to the :class:`~.quality.LocalizationMonitor`;
4. a kidnap (a tight set whose scan fit stays poor, judged per beam: :attr:`LocalizationMonitor.kidnapped`,
   :func:`~.quality.scan_fit`) re-draws the
   particles around the estimate (:func:`~.quality.respread_after_kidnap`) and starts re-localising --
   but only once armed: the filter must have been localised since the last (re)initialisation. Before
   that, a tight set with a poor fit is a filter still converging from an uncertain start (in the open
   headland the scan sees little and the set can contract before the row ends pin it), not a robot that
   was moved; re-spreading it there throws away what it has learnt and can lose it for good. After a
   detected kidnap the supervisor stays armed: the filter had been right, so a re-spread set that agrees
   on a pose the scan does not fit is wrong again;
5. while not localised, widen the reported covariance (:func:`~.quality.reported_covariance`).

(Re)initialisation -- :meth:`initialise` (a new map, ``/initialpose``), :meth:`global_localization` --
disarms the kidnap detection until the filter is localised again.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from cottonsim_common.pose import Pose2D, compose
from cottonsim_common.validation import require_instance
from ..core.grid import GridSpec
from .amcl import Amcl, AmclResult
from .free_space_model import FreeSpaceCheckedField, FreeSpaceConfig
from .quality import (LocalizationMonitor, LocalizationQualityConfig, StationaryUpdatePolicy, particle_spread,
                      reported_covariance, respread_after_kidnap, scan_fit, scan_hit_fraction)
from .sensor_models import Scan

FREE_SPACE_MODES = ("off", "relocalizing", "always")
STANDING_M = 1e-3           # odometry that moved less than this between two scans: the robot stands [m]
STANDING_RAD = 1e-3         # ... and turned less than this [rad]


@dataclass(frozen=True)
class SupervisorConfig:
    """The policy's settings.

    free_space_mode: the free-space check of the beams (:mod:`.free_space_model`): "off", "relocalizing"
        (only while not localised: initial convergence, after a kidnap) or "always"; default "relocalizing";
    free_space: that check's settings (:class:`~.free_space_model.FreeSpaceConfig`);
    quality: the localised signal's and the kidnap handling's thresholds
        (:class:`~.quality.LocalizationQualityConfig`).
    """

    free_space_mode: str = "relocalizing"
    free_space: FreeSpaceConfig = field(default_factory=FreeSpaceConfig)
    quality: LocalizationQualityConfig = field(default_factory=LocalizationQualityConfig)

    def __post_init__(self) -> None:
        if self.free_space_mode not in FREE_SPACE_MODES:
            raise ValueError(f"free_space_mode must be one of {FREE_SPACE_MODES}, got {self.free_space_mode!r}")
        require_instance("free_space", self.free_space, FreeSpaceConfig)
        require_instance("quality", self.quality, LocalizationQualityConfig)


@dataclass(frozen=True)
class SupervisorStep:
    """What one :meth:`LocalizationSupervisor.step` did.

    result: AMCL's output (after a filter update while not localised: with the widened covariance);
    localized: the signal after this step; changed: it switched on this step;
    kidnapped: a kidnap was detected and the particles re-spread on this step;
    std_xy_m [m], std_yaw_rad [rad], hit_fraction: the spread and scan fit of this filter update (NaN
        without one); stationary_poor_fit: the update ran although the robot stood because the scan fitted
        the map poorly at the estimate; particles: a copy of the set after the step (None without update).
    """

    result: AmclResult
    localized: bool
    changed: bool = False
    kidnapped: bool = False
    std_xy_m: float = math.nan
    std_yaw_rad: float = math.nan
    hit_fraction: float = math.nan
    stationary_poor_fit: Optional[float] = None
    particles: Optional[np.ndarray] = None

    @property
    def updated(self) -> bool:
        return self.result.updated


class LocalizationSupervisor:
    """Runs :class:`~.amcl.Amcl` with the localised signal and the kidnap handling (see the module doc)."""

    def __init__(self, amcl: Amcl, config: SupervisorConfig = SupervisorConfig()) -> None:
        require_instance("amcl", amcl, Amcl)
        require_instance("config", config, SupervisorConfig)
        self.amcl = amcl
        self.config = config
        self.monitor = LocalizationMonitor(config.quality)
        self.stationary = StationaryUpdatePolicy(config.quality)
        self.armed = False                      # kidnap detection: on once localised since (re)initialisation
        self.kidnaps = 0
        self._map_to_odom: Optional[Pose2D] = None
        self._last_odom: Optional[Pose2D] = None

    @property
    def localized(self) -> bool:
        return self.monitor.localized

    @property
    def has_map(self) -> bool:
        return self.amcl.field is not None

    # --- (re)initialisation ---------------------------------------------------------
    def set_map(self, occupancy, spec: GridSpec, initial_pose=None) -> None:
        """A new map: rebuild the fields and start again from ``initial_pose`` (default AMCL's configured one)."""
        self.amcl.set_map(occupancy, spec)
        if self.config.free_space_mode != "off":
            self.amcl.field = FreeSpaceCheckedField(self.amcl.field, self.config.free_space)
        self.initialise(self.amcl.config.initial_pose if initial_pose is None else initial_pose,
                        relocalize=False)

    def initialise(self, pose, covariance=None, relocalize: bool = True) -> None:
        """Gaussian set around ``pose`` (covariance default: AMCL's initial one); not localised, disarmed.
        relocalize: update without motion too until localised (a robot held by a paused navigator)."""
        if not self.has_map:
            raise ValueError("initialise needs a map: call set_map first")
        self.amcl.initialise(pose, covariance)
        self._reinitialised(relocalize)

    def global_localization(self) -> None:
        """Spread the particles over the map's free space; not localised, disarmed, updates without motion."""
        self.amcl.global_localization()
        self._reinitialised(True)

    def _reinitialised(self, relocalize: bool) -> None:
        self.monitor.reset()
        self.armed = False
        if relocalize:
            self.stationary.start_relocalizing()
        else:
            self.stationary.stop_relocalizing()

    def respread_after_kidnap(self, pose) -> None:
        """What a detected kidnap does: re-draw the particles around ``pose`` (x_m, y_m, yaw_rad; the wrong
        estimate, :func:`~.quality.respread_after_kidnap`), not localised, re-localise with updates without
        motion too; the detection stays armed (see the module doc)."""
        respread_after_kidnap(self.amcl, pose, self.config.quality)
        self.monitor.reset()
        self.stationary.start_relocalizing()
        self.armed = True
        self.kidnaps += 1

    # --- one scan ---------------------------------------------------------------------
    def step(self, now_s: float, odom, scan: Scan) -> SupervisorStep:
        """Feed one scan with its time ``now_s`` [s] and the odometry pose (x_m, y_m, yaw_rad) at that time."""
        if not self.has_map:
            raise ValueError("step needs a map: call set_map first")
        if isinstance(now_s, bool) or not isinstance(now_s, (int, float)) or not math.isfinite(now_s):
            raise ValueError(f"now_s must be a finite number, got {now_s!r}")
        odom = Pose2D(*(float(v) for v in odom))
        poor_fit = self._before_update(now_s, odom, scan)
        result = self.amcl.update(odom, scan)
        if not result.updated:
            self._map_to_odom = result.map_to_odom
            return SupervisorStep(result, self.monitor.localized)
        q = self.config.quality
        std_xy, std_yaw = particle_spread(self.amcl.particles, self.amcl.filter.weights)
        pose = (result.pose.x_m, result.pose.y_m, result.pose.yaw_rad)
        hits, judged = scan_fit(self.amcl.field, pose, scan, q.hit_distance_m, q.max_crossed_m)
        was = self.monitor.localized
        now = self.monitor.update(std_xy, std_yaw, hits, judged)
        if now:
            self.armed = True
        kidnapped = self.armed and self.monitor.kidnapped
        if kidnapped:          # confidently wrong: spread the particles around the estimate again
            self.respread_after_kidnap(pose)
            now = False
        particles = self.amcl.particles.copy()
        if not now:            # not localised: the whole set's spread, more while the scan does not fit
            cov = reported_covariance(result.covariance, particles, None if kidnapped else self.amcl.filter.weights,
                                      False, hits, pose[2], q)
            result = dataclasses.replace(result, covariance=cov)
        self._map_to_odom = result.map_to_odom
        return SupervisorStep(result, now, now != was, kidnapped, std_xy, std_yaw, hits, poor_fit, particles)

    def _before_update(self, now_s: float, odom: Pose2D, scan: Scan) -> Optional[float]:
        """Free-space check on/off; a filter update without motion when the stationary policy asks.
        Returns the scan fit at the estimate when a poor one asked for that update, else None."""
        field_ = self.amcl.field
        if isinstance(field_, FreeSpaceCheckedField):
            field_.enabled = self.config.free_space_mode == "always" or not self.monitor.localized
        q = self.config.quality
        hits = None
        if self.monitor.localized and self._map_to_odom is not None and self.stationary.due(now_s):
            here = compose(self._map_to_odom, odom)
            hits = scan_hit_fraction(field_, (here.x_m, here.y_m, here.yaw_rad), scan, q.hit_distance_m,
                                     q.max_crossed_m)
        last, self._last_odom = self._last_odom, odom
        standing = last is not None and abs(odom.x_m - last.x_m) < STANDING_M and abs(odom.y_m - last.y_m) < \
            STANDING_M and abs(odom.yaw_rad - last.yaw_rad) < STANDING_RAD
        lost = self.armed and not self.monitor.localized and standing
        update, roughen = self.stationary.decide(now_s, self.monitor.localized, hits, self.monitor.suspect or lost)
        if roughen:
            self.amcl.filter.roughen(q.roughen_std_xy_m, q.roughen_std_yaw_rad)
        if update:
            self.amcl.request_update()
            return hits
        return None
