"""Rao-Blackwellised particle-filter SLAM (the pure core of a gmapping-like mapper).

Why: the paper's map-based mode first drives the farm with gmapping to build
the occupancy map that AMCL later localises in. This module does that job
without ROS: feed it odometry poses and laser scans, read back the map, the
robot's map pose and the map -> odom correction.

Each particle is a pose trajectory hypothesis with its own occupancy map
(log-odds). One update (when the robot moved ``linear_update_m`` /
``angular_update_rad`` or ``temporal_update_s`` passed), as gmapping does it:

1. predict every particle with the odometry motion model (gmapping's
   srr/srt/str/stt noise, mapped onto the alpha model of
   :mod:`..localization.motion_models` as alpha = s^2);
2. refine each pose by matching the scan against the particle's own map
   (:mod:`.scan_matcher`; rejected matches keep the odometry pose);
3. add the match log-likelihood ``-sum(d^2) / (2 lsigma^2)`` to the
   particle's accumulated log weight (normalised like gmapping with gain
   ``1 / (ogain * N)``);
4. resample (systematic) when N_eff / N < ``resample_threshold``;
5. integrate the scan into each particle's map: Bresenham rays add
   ``logodds_miss`` to the cells they cross and ``logodds_hit`` to the end
   cell (beams longer than ``max_urange_m`` or without return only clear up to
   ``max_urange_m``).

Crop rows and along-row drift: rows are long corridors of nearly touching
plants, so the scan constrains the sideways position and heading well but the
along-row position only weakly (and periodically). The matcher therefore
carries an anisotropic odometry prior in the robot frame (tight along the
heading, loose sideways; see :class:`ScanMatcherConfig`), i.e. along the row
odometry is trusted and the scan corrects the rest; poor matches fall back to
odometry entirely.

Memory: each particle's map is a ``tiled_map.TiledLogOddsMap`` (64 x 64-cell
tiles, only where something was observed, shared copy-on-write between
resampled particles): 30 particles over the farm cost a few MB, not 30 full
4000 x 4000 grids.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Tuple

import numpy as np

from cottonsim_common.angles import wrap_angle
from cottonsim_common.pose import Pose2D, compose, inverse
from cottonsim_common.validation import require_fields, require_instance, require_int

from ..core.grid import GridSpec
from ..localization.motion_models import OdometryMotionModelConfig, _as_pose_array, sample_motion_model_odometry
from ..localization.particle_filter import effective_sample_size, systematic_resample_indices, weight_entropy
from ..localization.sensor_models import Scan
from .heading_fusion import HeadingFuser
from .scan_matcher import ScanMatcher, ScanMatcherConfig, build_match_field
from .tiled_map import LOGODDS_SCALE, TILE, TiledLogOddsMap, integrate_beams


@dataclass(frozen=True)
class SlamConfig:
    """RBPF-SLAM parameters (gmapping names in brackets; defaults = the original's values).

    particles: number of particles [particles 100; 30 is the benchmark point];
    max_urange_m: beams are used up to this range [maxUrange 5.5];
    max_range_m: readings at or beyond this count as no return [maxRange 6.1];
    linear_update_m, angular_update_rad: motion before a scan is processed [linearUpdate 0.3, angularUpdate 0.5];
    temporal_update_s: also process after this much time without motion (<= 0: off) [temporalUpdate 2.0];
    resample_threshold: resample when N_eff / N falls below [resampleThreshold 0.5];
    delta_m: map resolution [delta 0.05];
    xmin_m, ymin_m, xmax_m, ymax_m: map extent [xmin.. +/-100];
    srr, srt, str_, stt: odometry noise (trans<-trans, trans<-rot, rot<-trans, rot<-rot) [srr 0.1, srt 0.2, str 0.1, stt 0.2];
    lsigma_m: end-point sigma of the particle likelihood [lsigma 0.075];
    ogain: likelihood smoothing gain [ogain 3.0];
    lskip: use every (lskip+1)-th beam for matching [lskip 0];
    match_max_beams: at most this many evenly spaced end points are matched (a speed bound of this port);
    logodds_hit, logodds_miss, logodds_clamp: map update per hit / pass and the |log-odds| bound;
    occupied_prob: cells above this probability are occupied (100) in the output map;
    heading_tau_s: time constant of the IMU heading correction [s] (see :class:`HeadingFuser`; used only
        when :meth:`RbpfSlam.update` gets an IMU yaw);
    heading_track_rate: the heading correction also tracks the odometry heading's drift rate (a second-order
        loop, no lag for a steady gyro drift) instead of a first-order low-pass;
    heading_sigma_rad: with the IMU, each particle's predicted yaw is the fused heading plus noise of this std
        (an absolute heading, not an accumulated one) [rad]; the matcher's prior_sigma_yaw_rad then bounds
        how far the scan may turn it;
    matcher: the scan matcher's parameters.
    """

    particles: int = 100
    max_urange_m: float = 5.5
    max_range_m: float = 6.1
    linear_update_m: float = 0.3
    angular_update_rad: float = 0.5
    temporal_update_s: float = 2.0
    resample_threshold: float = 0.5
    delta_m: float = 0.05
    xmin_m: float = -100.0
    ymin_m: float = -100.0
    xmax_m: float = 100.0
    ymax_m: float = 100.0
    srr: float = 0.1
    srt: float = 0.2
    str_: float = 0.1
    stt: float = 0.2
    lsigma_m: float = 0.075
    ogain: float = 3.0
    lskip: int = 0
    match_max_beams: int = 90
    logodds_hit: float = 0.85
    logodds_miss: float = -0.05
    logodds_clamp: float = 3.5
    occupied_prob: float = 0.65
    heading_tau_s: float = 5.0
    heading_track_rate: bool = True
    heading_sigma_rad: float = 0.005
    matcher: ScanMatcherConfig = field(default_factory=ScanMatcherConfig)

    def __post_init__(self) -> None:
        require_int("particles", self.particles, 1)
        require_int("match_max_beams", self.match_max_beams, 3)
        require_int("lskip", self.lskip, 0)
        require_fields(self, positive=("max_urange_m", "max_range_m", "delta_m", "lsigma_m", "ogain", "logodds_hit",
                                       "logodds_clamp", "heading_tau_s"),
                       non_negative=("linear_update_m", "angular_update_rad", "srr", "srt", "str_", "stt",
                                     "heading_sigma_rad"),
                       flags=("heading_track_rate",))
        if not (isinstance(self.temporal_update_s, (int, float)) and not math.isnan(self.temporal_update_s)):
            raise ValueError(f"temporal_update_s must be a number, got {self.temporal_update_s!r}")
        if self.max_urange_m > self.max_range_m:
            raise ValueError(f"max_urange_m ({self.max_urange_m}) must not exceed max_range_m ({self.max_range_m})")
        if not (0 <= self.resample_threshold <= 1):
            raise ValueError(f"resample_threshold must lie in [0, 1], got {self.resample_threshold!r}")
        if not (math.isfinite(self.logodds_miss) and self.logodds_miss < 0):
            raise ValueError(f"logodds_miss must be a finite number < 0, got {self.logodds_miss!r}")
        if self.logodds_clamp * LOGODDS_SCALE > 30000:
            raise ValueError(f"logodds_clamp must be <= 300 (int16 storage), got {self.logodds_clamp}")
        if not (0.5 < self.occupied_prob < 1):
            raise ValueError(f"occupied_prob must lie in (0.5, 1), got {self.occupied_prob!r}")
        for lo, hi in (("xmin_m", "xmax_m"), ("ymin_m", "ymax_m")):
            a, b = getattr(self, lo), getattr(self, hi)
            if not (math.isfinite(a) and math.isfinite(b) and a < b):
                raise ValueError(f"need finite {lo} < {hi}, got {a}, {b}")
        require_instance("matcher", self.matcher, ScanMatcherConfig)

    def motion_config(self) -> OdometryMotionModelConfig:
        """gmapping's noise as the alpha model: rot<-rot stt^2, rot<-trans str^2, trans<-trans srr^2, trans<-rot srt^2."""
        # gmapping's s* are standard deviations per unit: the variance form ("diff-corrected") with alpha = s^2
        return OdometryMotionModelConfig(self.stt ** 2, self.str_ ** 2, self.srr ** 2, self.srt ** 2,
                                         model="diff-corrected")

    def map_spec(self) -> GridSpec:
        """The whole map extent as a grid (cells are allocated lazily in tiles)."""
        w = int(math.ceil((self.xmax_m - self.xmin_m) / self.delta_m))
        h = int(math.ceil((self.ymax_m - self.ymin_m) / self.delta_m))
        return GridSpec(self.delta_m, w, h, self.xmin_m, self.ymin_m)


@dataclass(frozen=True)
class SlamResult:
    """Output of :meth:`RbpfSlam.update`.

    updated: the scan was processed; pose: best particle's pose in the map frame;
    map_to_odom: the correction to publish as TF; neff: effective sample size;
    entropy: entropy of the particle weights [nats]; resampled: the set was resampled;
    match_score: best particle's scan-match score (0..1, 0 when no match ran).
    """

    updated: bool
    pose: Pose2D
    map_to_odom: Pose2D
    neff: float
    entropy: float
    resampled: bool
    match_score: float


class RbpfSlam:
    """gmapping-style SLAM: feed (odometry pose, scan, time) with :meth:`update`; read :meth:`occupancy`.

    The map frame is the odometry frame at the first scan (map -> odom starts as identity).
    """

    def __init__(self, config: SlamConfig = SlamConfig(), rng: Optional[np.random.Generator] = None) -> None:
        require_instance("config", config, SlamConfig)
        self.config = config
        self.rng = rng if rng is not None else np.random.default_rng()
        self.spec = config.map_spec()
        self.matcher = ScanMatcher(config.matcher)
        self._motion = config.motion_config()
        self.poses = np.zeros((config.particles, 3))
        self.log_weights = np.zeros(config.particles)
        self.maps = [TiledLogOddsMap(self.spec) for _ in range(config.particles)]
        self._last_odom: Optional[np.ndarray] = None
        self._last_time_s: Optional[float] = None
        self._map_to_odom = Pose2D(0.0, 0.0, 0.0)
        self._scores = np.zeros(config.particles)
        self._heading = HeadingFuser(config.heading_tau_s, track_rate=config.heading_track_rate)
        self._imu_seen = False
        self.n_updates = 0

    # --- weights -------------------------------------------------------------------
    def normalised_weights(self) -> np.ndarray:
        """gmapping's normalise: exp(gain * (l - max l)), gain = 1 / (ogain * N), summed to 1."""
        gain = 1.0 / (self.config.ogain * self.config.particles)
        w = np.exp(gain * (self.log_weights - self.log_weights.max()))
        return w / w.sum()

    @property
    def best_index(self) -> int:
        return int(np.argmax(self.log_weights))

    # --- the update ------------------------------------------------------------------
    def update(self, odom_pose, scan: Scan, stamp_s: float = 0.0, imu_yaw_rad: Optional[float] = None) -> SlamResult:
        """Process one scan taken at odometry pose ``odom_pose`` (x_m, y_m, yaw_rad) and time ``stamp_s``.

        ``imu_yaw_rad``: the IMU's absolute yaw of base_link at that time (any fixed reference) or None.
        Given, the particles move with the odometry whose heading the IMU holds (:class:`HeadingFuser`);
        call with every scan (also those not processed) so that the filter sees the whole odometry.
        """
        require_instance("scan", scan, Scan)
        raw = _as_pose_array(odom_pose, "odom_pose")
        if not (isinstance(stamp_s, (int, float)) and math.isfinite(stamp_s)):
            raise ValueError(f"stamp_s must be a finite number, got {stamp_s!r}")
        if imu_yaw_rad is not None or self._imu_seen:
            self._imu_seen = True
            odom = self._heading.update(raw, imu_yaw_rad, float(stamp_s))
        else:
            odom = raw
        cfg = self.config
        first = self._last_odom is None
        resampled = False
        if first:
            self.poses[:] = odom
        else:
            d = odom - self._last_odom
            moved = (math.hypot(d[0], d[1]) >= cfg.linear_update_m
                     or abs(wrap_angle(d[2])) >= cfg.angular_update_rad)
            timed = cfg.temporal_update_s > 0 and stamp_s - self._last_time_s >= cfg.temporal_update_s
            if not (moved or timed):
                return self._result(False, False, raw)
            self.poses = sample_motion_model_odometry(self.poses, self._last_odom, odom, self._motion, self.rng)
            if self._imu_seen:     # the heading is the IMU's (absolute): re-anchor every particle's yaw to it
                self.poses[:, 2] = odom[2] + self.rng.normal(0.0, cfg.heading_sigma_rad, cfg.particles)
        hits, ends, hit_mask = self._beams(scan)
        if not first:
            self._match_all(hits)
            w = self.normalised_weights()
            if effective_sample_size(w) < cfg.resample_threshold * cfg.particles:
                self._resample(w)
                resampled = True
        self._integrate_all(scan, ends, hit_mask)
        self._last_odom = odom.copy()
        self._last_time_s = float(stamp_s)
        self.n_updates += 1
        best = self.poses[self.best_index]
        self._map_to_odom = compose(Pose2D(*best), inverse(Pose2D(*raw)))
        return self._result(True, resampled, raw)

    def _result(self, updated: bool, resampled: bool, odom: np.ndarray) -> SlamResult:
        w = self.normalised_weights()
        return SlamResult(updated, compose(self._map_to_odom, Pose2D(*odom)), self._map_to_odom,
                          effective_sample_size(w), weight_entropy(w), resampled,
                          float(self._scores[self.best_index]))

    def _beams(self, scan: Scan):
        """Robot-frame end points: hits for matching (< max_urange), ray ends and hit flags for the map."""
        cfg = self.config
        r = scan.ranges_m.copy()
        with np.errstate(invalid="ignore"):
            usable = ~np.isnan(r) & (r >= scan.range_min_m)
            no_return = ~np.isfinite(r) | (r >= scan.range_max_m) | (r >= cfg.max_range_m)
        hit = usable & ~no_return & (r < cfg.max_urange_m)
        ray_r = np.where(hit, r, cfg.max_urange_m)
        keep = usable
        ends = scan.points_in_robot_frame(ray_r[keep], scan.angles_rad[keep])
        hit_mask = hit[keep]
        step = cfg.lskip + 1
        hits = scan.points_in_robot_frame(r[hit][::step], scan.angles_rad[hit][::step])
        return hits, ends, hit_mask

    def _window(self, pose: np.ndarray, pts: np.ndarray, margin_m: float):
        """Tile range covering the robot and the end points placed at ``pose``, plus a margin."""
        c, s = math.cos(pose[2]), math.sin(pose[2])
        wx = pose[0] + c * pts[:, 0] - s * pts[:, 1]
        wy = pose[1] + s * pts[:, 0] + c * pts[:, 1]
        xs = np.append(wx, pose[0])
        ys = np.append(wy, pose[1])
        (mx0, mx1), (my0, my1) = self.spec.world_to_map(
            np.array([xs.min() - margin_m, xs.max() + margin_m]), np.array([ys.min() - margin_m, ys.max() + margin_m]))
        return self.maps[0].tile_range(int(mx0), int(my0), int(mx1), int(my1))

    def _match_all(self, hits: np.ndarray) -> None:
        cfg = self.config
        thr = int(round(LOGODDS_SCALE * math.log(cfg.occupied_prob / (1 - cfg.occupied_prob))))
        inv2 = 1.0 / (2.0 * cfg.lsigma_m ** 2)
        margin = cfg.matcher.max_dist_m + 0.5
        self._scores[:] = 0.0
        if hits.shape[0] == 0:
            return
        if hits.shape[0] > cfg.match_max_beams:
            hits = hits[np.round(np.linspace(0, hits.shape[0] - 1, cfg.match_max_beams)).astype(np.int64)]
        for i in range(cfg.particles):
            p = self.poses[i]
            tr = self._window(p, hits, margin)
            dense = self.maps[i].read(tr)
            ws = self.maps[i].window_spec(tr)
            # crop the tile-aligned window to the end points' box + margin: the distance
            # transform's cost is proportional to the cells it covers
            c, s = math.cos(p[2]), math.sin(p[2])
            wx = p[0] + c * hits[:, 0] - s * hits[:, 1]
            wy = p[1] + s * hits[:, 0] + c * hits[:, 1]
            (cx0, cx1), (cy0, cy1) = ws.world_to_map(np.array([wx.min() - margin, wx.max() + margin]),
                                                     np.array([wy.min() - margin, wy.max() + margin]))
            cx0, cy0 = max(int(cx0), 0), max(int(cy0), 0)
            cx1, cy1 = min(int(cx1), ws.width - 1), min(int(cy1), ws.height - 1)
            if cx1 < cx0 or cy1 < cy0:      # the scan lies off the map extent: keep odometry
                continue
            crop = dense[cy0:cy1 + 1, cx0:cx1 + 1]
            cs = GridSpec(ws.resolution_m, crop.shape[1], crop.shape[0],
                          ws.origin_x_m + cx0 * ws.resolution_m, ws.origin_y_m + cy0 * ws.resolution_m)
            fld = build_match_field(crop > thr, cs, cfg.matcher.max_dist_m)
            res = self.matcher.match(fld, self.poses[i], hits)
            if res.accepted:
                self.poses[i] = res.pose
                d = self.matcher.distances(fld, res.pose, hits)
                self.log_weights[i] += -float(np.sum(d * d)) * inv2
            self._scores[i] = res.score

    def _resample(self, w: np.ndarray) -> None:
        idx = systematic_resample_indices(w, self.config.particles, self.rng)
        parents_used = set()
        new_maps = []
        for j in idx:
            j = int(j)
            if j in parents_used:
                new_maps.append(self.maps[j].clone())
            else:
                parents_used.add(j)
                new_maps.append(self.maps[j])
        self.maps = new_maps
        self.poses = self.poses[idx].copy()
        self._scores = self._scores[idx].copy()
        self.log_weights = np.zeros(self.config.particles)

    def _integrate_all(self, scan: Scan, ends: np.ndarray, hit_mask: np.ndarray) -> None:
        cfg = self.config
        if ends.shape[0] == 0:
            return
        lx, ly, _ = scan.laser_pose
        add_miss = int(round(cfg.logodds_miss * LOGODDS_SCALE))
        add_hit = int(round(cfg.logodds_hit * LOGODDS_SCALE))
        clamp = int(round(cfg.logodds_clamp * LOGODDS_SCALE))
        hit_u8 = hit_mask.astype(np.uint8)
        for i in range(cfg.particles):
            p = self.poses[i]
            tr = self._window(p, ends, 0.1)
            m = self.maps[i]
            dense = m.read(tr)
            ws = m.window_spec(tr)
            c, s = math.cos(p[2]), math.sin(p[2])
            ox = p[0] + c * lx - s * ly
            oy = p[1] + s * lx + c * ly
            emx, emy = ws.world_to_map(p[0] + c * ends[:, 0] - s * ends[:, 1], p[1] + s * ends[:, 0] + c * ends[:, 1])
            omx, omy = ws.world_to_map(ox, oy)
            touched = np.zeros((dense.shape[0] // TILE, dense.shape[1] // TILE), dtype=np.bool_)
            grid = dense.astype(np.int32)
            integrate_beams(grid, touched, int(omx), int(omy), emx.astype(np.int64), emy.astype(np.int64), hit_u8,
                       add_miss, add_hit, clamp)
            m.write(tr, grid.astype(np.int16), touched)

    # --- outputs ------------------------------------------------------------------------
    @property
    def map_to_odom(self) -> Pose2D:
        return self._map_to_odom

    def occupancy(self, particle: Optional[int] = None, crop: bool = True) -> Tuple[np.ndarray, GridSpec]:
        """The (best) particle's map as nav_msgs/OccupancyGrid values and its GridSpec.

        100 where p(occupied) > occupied_prob, -1 where never observed, 0 elsewhere.
        ``crop`` limits the grid to the tiles that hold observations (else the full extent).
        """
        i = self.best_index if particle is None else int(particle)
        if not (0 <= i < self.config.particles):
            raise ValueError(f"particle must lie in 0..{self.config.particles - 1}, got {particle!r}")
        m = self.maps[i]
        if crop and m.tiles:
            keys = np.array(list(m.tiles.keys()))
            tr = (int(keys[:, 1].min()), int(keys[:, 0].min()), int(keys[:, 1].max()), int(keys[:, 0].max()))
        else:
            tr = m.tile_range(0, 0, self.spec.width - 1, self.spec.height - 1)
        dense = m.read(tr)
        ws = m.window_spec(tr)
        thr = LOGODDS_SCALE * math.log(self.config.occupied_prob / (1 - self.config.occupied_prob))
        occ = np.zeros(dense.shape, dtype=np.int8)
        occ[dense == 0] = -1
        occ[dense > thr] = 100
        if not crop:   # trim the padding of the last tiles to the configured extent
            occ = occ[:self.spec.height, :self.spec.width]
            ws = self.spec
        return occ, ws

    def memory_bytes(self) -> int:
        """Bytes held by distinct map tiles over all particles (shared tiles counted once)."""
        seen = {}
        for m in self.maps:
            for t in m.tiles.values():
                seen[id(t)] = t.nbytes
        return int(sum(seen.values()))

    def entropy(self) -> float:
        return weight_entropy(self.normalised_weights())
