"""AMCL: adaptive Monte-Carlo localisation of the robot in a known map (pure core of ROS amcl).

Why: in the paper's map-based mode the robot follows waypoints given in the
frame of a map built beforehand by SLAM; AMCL estimates where the robot is in
that map from wheel odometry and the laser scan, and provides the map -> odom
correction that turns odometry (smooth, drifting) into map poses.

One filter cycle (:meth:`Amcl.update`), as in ROS amcl:

1. Wait until odometry moved more than ``update_min_d_m`` (in x or y) or
   turned more than ``update_min_a_rad`` since the last filter update
   (the first scan after (re)initialisation is always used).
2. Move every particle with the sampled differential odometry model
   (:mod:`.motion_models`).
3. Weigh particles with the likelihood-field laser model (:mod:`.sensor_models`).
4. Every ``resample_interval`` updates, resample with KLD-sampling and
   (when the recovery alphas are > 0) random particles in free space
   (:mod:`.particle_filter`).
5. Report the weighted mean and covariance of the heaviest particle cluster,
   and ``map_to_odom = estimate (+) inverse(odom)``.

Between filter updates :meth:`update` returns the last correction applied to
the current odometry, so callers always get a current map pose.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from cottonsim_common.angles import wrap_angle
from cottonsim_common.pose import Pose2D, compose, inverse
from cottonsim_common.validation import (require_fields, require_finite_values, require_instance, require_int,
                                         require_number)
from ..core.grid import GridSpec
from .motion_models import OdometryMotionModelConfig, _as_pose_array, motion_parts, sample_motion_model_odometry
from .particle_filter import FreeSpaceSampler, ParticleFilter, ParticleFilterConfig
from .sensor_models import LikelihoodField, LikelihoodFieldConfig, Scan


# the sub-models' defaults, declared once in their own configs
_MOTION, _SENSOR, _FILTER = OdometryMotionModelConfig(), LikelihoodFieldConfig(), ParticleFilterConfig()


@dataclass(frozen=True)
class AmclConfig:
    """All AMCL parameters (ROS amcl names minus prefixes; defaults = the original's values).

    alpha1..alpha5: odometry noise (odom_alpha1..5, diff model; alpha5 unused);
    odom_model_type: "diff" (amcl's original sampling, the original's choice) or "diff-corrected"
        (see :mod:`.motion_models`: the same alphas give ~9x more noise per 0.25 m step);
    odom_max_step_m [m], odom_max_step_rad [rad]: a filter update that comes late (the odometry moved
        further / turned more than this since the last one) samples the motion noise in parts of at
        most this size, so the spread does not depend on how often the filter ran (not in ROS amcl;
        0 = one piece, as amcl; see :mod:`.motion_models`). Defaults 0.5 m, 0.5 rad: 2x and 2.5x the
        update thresholds, so an update on time is sampled as before;
    min_particles, max_particles, kld_err, kld_z: KLD-sampling (see ParticleFilterConfig);
    max_beams, laser_max_range_m, laser_min_range_m, z_hit, z_rand, sigma_hit_m,
    likelihood_max_dist_m: likelihood-field model (laser_* parameters);
    laser_model_type: "likelihood_field" (the original's) or "likelihood_field_prob" (see LikelihoodFieldConfig);
    update_min_d_m [m], update_min_a_rad [rad]: motion needed before a filter update;
    resample_interval: filter updates between resamplings;
    recovery_alpha_slow, recovery_alpha_fast: augmented-MCL rates (0 = off, amcl's default);
    initial_pose: (x_m, y_m, yaw_rad) used when update() runs before initialise();
    initial_cov_xx_m2, initial_cov_yy_m2, initial_cov_aa_rad2: its covariance (amcl: 0.25, 0.25, (pi/12)^2);
    occupied_threshold: map values above this are obstacles for the likelihood field (0..100).
    """

    alpha1: float = _MOTION.alpha1
    alpha2: float = _MOTION.alpha2
    alpha3: float = _MOTION.alpha3
    alpha4: float = _MOTION.alpha4
    alpha5: float = _MOTION.alpha5
    odom_model_type: str = _MOTION.model
    odom_max_step_m: float = 0.5
    odom_max_step_rad: float = 0.5
    min_particles: int = _FILTER.min_particles
    max_particles: int = _FILTER.max_particles
    kld_err: float = _FILTER.kld_err
    kld_z: float = _FILTER.kld_z
    max_beams: int = _SENSOR.max_beams
    laser_max_range_m: float = _SENSOR.max_range_m
    laser_min_range_m: float = _SENSOR.min_range_m
    z_hit: float = _SENSOR.z_hit
    z_rand: float = _SENSOR.z_rand
    sigma_hit_m: float = _SENSOR.sigma_hit_m
    likelihood_max_dist_m: float = _SENSOR.likelihood_max_dist_m
    laser_model_type: str = _SENSOR.model
    update_min_d_m: float = 0.25
    update_min_a_rad: float = 0.2
    resample_interval: int = 1
    recovery_alpha_slow: float = _FILTER.alpha_slow
    recovery_alpha_fast: float = _FILTER.alpha_fast
    initial_pose: tuple = (0.0, 0.0, 0.0)
    initial_cov_xx_m2: float = 0.25
    initial_cov_yy_m2: float = 0.25
    initial_cov_aa_rad2: float = (math.pi / 12.0) ** 2
    occupied_threshold: int = 65

    def __post_init__(self) -> None:
        # The sub-configs validate their own fields and name them.
        self.motion_config()
        self.sensor_config()
        self.filter_config()
        require_fields(self, non_negative=("update_min_d_m", "update_min_a_rad", "initial_cov_xx_m2",
                                           "initial_cov_yy_m2", "initial_cov_aa_rad2"))
        require_int("resample_interval", self.resample_interval, 1)
        require_finite_values("initial_pose", self.initial_pose, 3)
        require_number("occupied_threshold", self.occupied_threshold, 0, 100)

    def motion_config(self) -> OdometryMotionModelConfig:
        return OdometryMotionModelConfig(self.alpha1, self.alpha2, self.alpha3, self.alpha4, self.alpha5,
                                         model=self.odom_model_type, max_step_m=self.odom_max_step_m,
                                         max_step_rad=self.odom_max_step_rad)

    def sensor_config(self) -> LikelihoodFieldConfig:
        return LikelihoodFieldConfig(self.z_hit, self.z_rand, self.sigma_hit_m, self.likelihood_max_dist_m,
                                     self.max_beams, self.laser_max_range_m, self.laser_min_range_m,
                                     model=self.laser_model_type)

    def filter_config(self) -> ParticleFilterConfig:
        return ParticleFilterConfig(self.min_particles, self.max_particles, self.kld_err, self.kld_z,
                                    alpha_slow=self.recovery_alpha_slow, alpha_fast=self.recovery_alpha_fast)

    def initial_covariance(self) -> np.ndarray:
        return np.diag([self.initial_cov_xx_m2, self.initial_cov_yy_m2, self.initial_cov_aa_rad2])


@dataclass(frozen=True)
class AmclResult:
    """Output of one :meth:`Amcl.update`.

    pose: robot pose in the map frame now; covariance: 3x3 (x, y, yaw) [m^2, rad^2];
    map_to_odom: the map -> odom transform (publish as TF);
    updated: a filter update ran on this scan; resampled: the set was resampled;
    n_particles: current set size; motion_parts: how many parts this update's odometry increment
    was sampled in (0: no motion update; > 1: a late update, see AmclConfig.odom_max_step_m).
    """

    pose: Pose2D
    covariance: np.ndarray
    map_to_odom: Pose2D
    updated: bool
    resampled: bool
    n_particles: int
    motion_parts: int = 0


class Amcl:
    """Adaptive Monte-Carlo localisation against an occupancy map.

    Usage::

        amcl = Amcl(AmclConfig(), rng=np.random.default_rng(0))
        amcl.set_map(occupancy, spec)                 # nav_msgs/OccupancyGrid values, GridSpec
        amcl.initialise(Pose2D(x, y, yaw), cov3x3)    # or amcl.global_localization()
        result = amcl.update(odom_pose, scan)         # every scan; odom_pose (x_m, y_m, yaw_rad)
    """

    def __init__(self, config: AmclConfig = AmclConfig(), rng: Optional[np.random.Generator] = None) -> None:
        require_instance("config", config, AmclConfig)
        self.config = config
        self.rng = rng if rng is not None else np.random.default_rng()
        self.filter = ParticleFilter(config.filter_config(), self.rng)
        self._motion = config.motion_config()
        self.field: Optional[LikelihoodField] = None
        self._free: Optional[FreeSpaceSampler] = None
        self._odom_ref: Optional[np.ndarray] = None     # odometry at the last filter update
        self._force_update = True
        self._updates = 0
        self._estimate = None
        self._map_to_odom = Pose2D(0.0, 0.0, 0.0)

    # --- set-up -----------------------------------------------------------------
    def set_map(self, occupancy, spec: GridSpec) -> None:
        """Use a new map (occupancy -1 / 0..100 on ``spec``): rebuilds the likelihood field."""
        self.field = LikelihoodField(occupancy, spec, self.config.sensor_config(), self.config.occupied_threshold)
        self._free = FreeSpaceSampler(occupancy, spec)

    def initialise(self, pose, covariance=None, n_particles: Optional[int] = None) -> None:
        """Gaussian particle set around ``pose`` (map frame); covariance 3x3, default from the config.

        n_particles: how many to draw (default max_particles). More than max_particles is allowed: the
        first resampling brings the set back within [min_particles, max_particles] (KLD-sampling), so a
        wide re-spread can be drawn densely for its first filter update only.
        """
        mean = _as_pose_array(pose, "pose")
        cov = self.config.initial_covariance() if covariance is None else covariance
        if n_particles is not None and (isinstance(n_particles, bool) or not isinstance(n_particles, int)
                                        or n_particles < 1):
            raise ValueError(f"n_particles must be an integer >= 1, got {n_particles!r}")
        self.filter.init_gaussian(mean, cov, n_particles)
        self._after_reinit()

    def global_localization(self) -> None:
        """Spread max_particles uniformly over the map's free cells (amcl's global_localization service)."""
        if self._free is None:
            raise ValueError("global_localization needs a map: call set_map first")
        self.filter.init_uniform(self._free)
        self._after_reinit()

    def request_update(self) -> None:
        """Run a filter update on the next scan even if odometry has not moved (re-localising while standing)."""
        self._force_update = True

    def _after_reinit(self) -> None:
        self._force_update = True
        self._updates = 0
        self._estimate = None

    @property
    def particles(self) -> np.ndarray:
        return self.filter.particles

    @property
    def initialised(self) -> bool:
        return self.filter.n > 0

    # --- the filter cycle ------------------------------------------------------------
    def update(self, odom_pose, scan: Scan) -> AmclResult:
        """Feed one scan with the odometry pose at its time; see the module docstring."""
        if self.field is None:
            raise ValueError("Amcl.update needs a map: call set_map first")
        require_instance("scan", scan, Scan)
        odom = _as_pose_array(odom_pose, "odom_pose")
        if not self.initialised:
            self.initialise(self.config.initial_pose)
        if self._odom_ref is None:
            self._odom_ref = odom.copy()
            self._force_update = True
        delta = odom - self._odom_ref
        moved = (abs(delta[0]) > self.config.update_min_d_m or abs(delta[1]) > self.config.update_min_d_m
                 or abs(wrap_angle(delta[2])) > self.config.update_min_a_rad)
        updated = resampled = False
        parts = 0
        if moved or self._force_update:
            if moved:
                parts = motion_parts(self._odom_ref, odom, self._motion)
                self.filter.particles = sample_motion_model_odometry(self.filter.particles, self._odom_ref, odom,
                                                                     self._motion, self.rng)
            self.filter.update_weights(self.field.weights(self.filter.particles, scan))
            self._updates += 1
            if self._updates % self.config.resample_interval == 0:
                self.filter.resample(self._free)
                resampled = True
            self._estimate = self.filter.estimate()
            mean = self._estimate.mean
            self._map_to_odom = compose(Pose2D(*mean), inverse(Pose2D(*odom)))
            self._odom_ref = odom.copy()
            self._force_update = False
            updated = True
        if self._estimate is None:
            self._estimate = self.filter.estimate()
        pose = compose(self._map_to_odom, Pose2D(*odom))
        return AmclResult(pose, self._estimate.covariance.copy(), self._map_to_odom, updated, resampled,
                          self.filter.n, parts)
