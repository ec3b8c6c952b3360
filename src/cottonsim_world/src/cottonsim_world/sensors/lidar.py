"""Velodyne VLP-16 LiDAR by batched ray casting in the sensor scene.

Why: navigation (PassThrough -> costmap, pointcloud_to_laserscan -> AMCL /
gmapping) needs the /points cloud of the robot's VLP-16. ``Vlp16Model``
casts one ray per (ring, azimuth) sample, adds Gaussian range noise and
returns the returns as numpy arrays. Two backends (``LidarConfig.backend``):

* 'numba' (default): ``sensors.fast.raycast`` descends a bounding volume
  hierarchy of the plants' mesh triangles (``SensorScene.fast_bvh``) with
  the ground as the analytic plane z = 0; casts against the meshes only (needs
  ``SceneConfig.collision_source == 'meshes'``);
* 'pybullet': the reference, ``rayTestBatch`` against
  ``SensorScene.ray_client`` (ground plane + plant collision shapes, meshes
  or primitives; at most 16,384 rays per call, pybullet's limit). Its
  collision world takes seconds to build and is built only when used.

Frame: the sensor frame ``velodyne`` (x forward, y left, z up). Rings are
numbered from the lowest beam (ring 0 at -15 deg) up, as the velodyne
driver does. The whole 360 deg sweep is taken at one instant (no motion
skew; at 0.5 m/s the robot moves 5 cm during a real 0.1 s sweep).

Bolls that have left their plant (``SensorScene.visibility``) return no
rays: the numba caster passes through their triangles, the pybullet world
removes their bodies.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np
import pybullet as pb

from cottonsim_common.validation import require_instance
from cottonsim_world.farm.model import SemanticClass
from cottonsim_world.sensors.fast.raycast import HIT_GROUND, cast_rays, gather_returns
from cottonsim_world.sensors.scene import BollVisibility, SensorScene, check_pose

LIDAR_BACKENDS = ("numba", "pybullet")
_MAX_RAYS_PER_BATCH = 16000   # pybullet documents 16384 but returns only 16383 results for 16384 rays


@dataclass(frozen=True)
class LidarConfig:
    """VLP-16 parameters. Defaults: the original's sensor.

    rings, min/max_elevation_rad: beam layout (evenly spaced, 2 deg apart by
    default); samples_per_ring: horizontal samples per revolution (real
    sensor at 10 Hz: 1800; 900 (0.4 deg) is the default because it still
    puts at least one sample in every 0.5 deg LaserScan bin at a quarter of
    the cost of 1800); rate_hz: revolutions per second (used by the bridge);
    min_range_m / max_range_m: returns outside are dropped [m];
    noise_std_m: Gaussian range noise [m]; backend: 'numba' (compiled BVH
    ray caster, fast, the default) or 'pybullet' (rayTestBatch, the
    reference); num_threads: rayTestBatch threads (0 = pybullet picks) or,
    for 'numba', the most worker threads (0 = numba's default); reflectivity per SemanticClass (plant,
    ground, sky (unused), boll) gives the intensity, scaled by 100 like the
    velodyne driver's 0-255 range; seed: noise.
    """

    rings: int = 16
    min_elevation_rad: float = math.radians(-15.0)
    max_elevation_rad: float = math.radians(15.0)
    samples_per_ring: int = 900
    rate_hz: float = 10.0
    min_range_m: float = 0.9
    max_range_m: float = 130.0
    noise_std_m: float = 0.008
    backend: str = "numba"
    num_threads: int = 2
    reflectivity: Tuple[float, float, float, float] = (0.45, 0.25, 0.0, 0.85)
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("rings", "samples_per_ring"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        if self.rings * self.samples_per_ring > 1_000_000:
            raise ValueError(f"rings * samples_per_ring must be <= 1e6, got {self.rings * self.samples_per_ring}")
        lo, hi = self.min_elevation_rad, self.max_elevation_rad
        if not (-math.pi / 2 < lo <= hi < math.pi / 2) or (self.rings > 1 and lo == hi):
            raise ValueError(f"min_elevation_rad/max_elevation_rad must satisfy -pi/2 < min < max < pi/2, "
                             f"got {lo}, {hi}")
        if not (self.rate_hz > 0.0 and math.isfinite(self.rate_hz)):
            raise ValueError(f"rate_hz must be > 0, got {self.rate_hz}")
        if not (0.0 <= self.min_range_m < self.max_range_m) or not math.isfinite(self.max_range_m):
            raise ValueError(f"min_range_m/max_range_m must satisfy 0 <= min < max < inf, got "
                             f"{self.min_range_m}, {self.max_range_m}")
        if not (self.noise_std_m >= 0.0 and math.isfinite(self.noise_std_m)):
            raise ValueError(f"noise_std_m must be >= 0, got {self.noise_std_m}")
        if self.backend not in LIDAR_BACKENDS:
            raise ValueError(f"backend must be one of {LIDAR_BACKENDS}, got {self.backend!r}")
        if not isinstance(self.num_threads, (int, np.integer)) or self.num_threads < 0:
            raise ValueError(f"num_threads must be an integer >= 0, got {self.num_threads!r}")
        if len(self.reflectivity) != 4 or not all(0.0 <= r <= 2.55 for r in self.reflectivity):
            raise ValueError(f"reflectivity must be 4 values in [0, 2.55], got {self.reflectivity!r}")

    def ring_elevations_rad(self) -> np.ndarray:
        """(rings,) beam elevations, ring 0 lowest [rad]."""
        if self.rings == 1:
            return np.array([self.min_elevation_rad])
        return np.linspace(self.min_elevation_rad, self.max_elevation_rad, self.rings)


@dataclass
class LidarScan:
    """One revolution, returns only (dropped rays are not listed).

    points (N, 3) float32 [m] in the sensor frame; ring (N,) uint16;
    intensity (N,) float32; azimuth_rad (N,) float32 in [-pi, pi);
    semantic (N,) uint8 SemanticClass of the surface hit (ground truth);
    plant_id (N,) int32, -1 where not a plant.
    """

    points: np.ndarray
    ring: np.ndarray
    intensity: np.ndarray
    azimuth_rad: np.ndarray
    semantic: np.ndarray
    plant_id: np.ndarray


class Vlp16Model:
    """Casts VLP-16 scans in a ``SensorScene``: ``scan(world_T_sensor) -> LidarScan``.

    The numba backend casts one warm-up scan in the constructor (compiles
    the kernel on the very first use; later processes load it from cache).
    """

    def __init__(self, scene: SensorScene, config: LidarConfig = LidarConfig()) -> None:
        require_instance("scene", scene, SensorScene)
        require_instance("config", config, LidarConfig)
        self.scene = scene
        self.config = config
        n = config.samples_per_ring
        az = -math.pi + 2.0 * math.pi * np.arange(n) / n
        el = config.ring_elevations_rad()
        ring, azi = np.meshgrid(np.arange(config.rings), np.arange(n), indexing="ij")
        self._ring = ring.ravel().astype(np.uint16)
        self._azimuth = az[azi.ravel()].astype(np.float32)
        e = el[self._ring]
        a = az[azi.ravel()]
        self._dirs = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=1)   # sensor frame
        self._rng = np.random.default_rng(config.seed)
        self._reflect = np.array(config.reflectivity, dtype=np.float32) * 100.0
        if config.backend == "numba":
            if scene.config.collision_source != "meshes":
                raise ValueError("LidarConfig.backend 'numba' casts against the plant meshes; "
                                 "SceneConfig.collision_source='primitives' needs backend='pybullet'")
            self._bvh = scene.fast_bvh
            self._plants = scene.fast_plants
            self._range = np.empty(len(self._dirs))
            self._hit = np.empty(len(self._dirs), np.int32)
            self._noise = np.empty(len(self._dirs))          # range noise of one scan [m]
            # compile or load the kernels now, not at the first scan (no noise drawn: the stream stays as it was)
            self._cast_into_buffers(np.eye(4), scene.visibility)
            gather_returns(self._range, self._hit, np.zeros(0), 0.0, 1.0, self._dirs, self._ring, self._azimuth,
                           self._plants.g_semantic, self._plants.g_plant, 1, 2, self._reflect)

    @property
    def ray_count(self) -> int:
        return len(self._dirs)

    def _scan_numba(self, pose: np.ndarray, visibility: BollVisibility) -> LidarScan:
        """``scan`` with the numba caster: the returns packed by one compiled pass (same result)."""
        cfg = self.config
        self._cast_into_buffers(pose, visibility)
        if cfg.noise_std_m > 0.0:
            # Generator.normal(0, std, n) is 0 + std * standard_normal() per draw: the same stream and values
            # (bar the sign of a zero), drawn into a reused buffer without normal()'s per-draw wrapper
            noise = self._noise
            self._rng.standard_normal(out=noise)
            noise *= cfg.noise_std_m
        else:
            noise = np.zeros(0)
        pts, ring, intensity, az, sem, pid = gather_returns(
            self._range, self._hit, noise, float(cfg.min_range_m), float(cfg.max_range_m), self._dirs, self._ring,
            self._azimuth, self._plants.g_semantic, self._plants.g_plant, int(SemanticClass.GROUND),
            int(SemanticClass.SKY), self._reflect)
        return LidarScan(points=pts, ring=ring, intensity=intensity, azimuth_rad=az, semantic=sem, plant_id=pid)

    def _cast_into_buffers(self, pose: np.ndarray, visibility: BollVisibility) -> None:
        """Run the numba caster from a checked pose into self._range / self._hit."""
        import numba
        b, cfg = self._bvh, self.config
        hidden = visibility.triangle_hidden
        if len(hidden) != len(b.tri):        # a snapshot taken before the tree was built
            hidden = self.scene.triangle_mask(visibility.hidden)
        before = numba.get_num_threads()
        if cfg.num_threads > 0:
            numba.set_num_threads(min(cfg.num_threads, numba.config.NUMBA_NUM_THREADS))
        try:
            cast_rays(np.ascontiguousarray(pose[:3, 3]), np.ascontiguousarray(pose[:3, :3]), self._dirs,
                      float(cfg.max_range_m), b.tri, b.tri_id, hidden, b.root_box, b.anchor, b.wide_record_f,
                      b.wide_record,
                      self._range, self._hit)
        finally:
            numba.set_num_threads(before)

    def _cast_numba(self, pose: np.ndarray, visibility: BollVisibility) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Ranges [m] (inf = no hit), semantic and plant id per ray with the numba caster."""
        self._cast_into_buffers(pose, visibility)
        hit = self._hit
        on_plant = hit >= 0
        safe = np.where(on_plant, hit, 0)
        sem = np.where(on_plant, self._plants.g_semantic[safe] if len(self._plants.g_semantic) else 0,
                       np.where(hit == HIT_GROUND, int(SemanticClass.GROUND), int(SemanticClass.SKY))).astype(np.uint8)
        pid = np.where(on_plant, self._plants.g_plant[safe] if len(self._plants.g_plant) else -1, -1).astype(np.int32)
        return self._range.copy(), sem, pid

    def _cast_pybullet(self, pose: np.ndarray, visibility: BollVisibility
                       ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Ranges [m] (inf = no hit), semantic and plant id per ray with rayTestBatch."""
        cfg = self.config
        world = self.scene.ray_world
        world.sync(visibility.hidden)
        origin = pose[:3, 3]
        dirs_w = self._dirs @ pose[:3, :3].T
        to = origin + dirs_w * cfg.max_range_m
        frm = np.broadcast_to(origin, to.shape)
        n = len(to)
        fraction = np.empty(n)
        body = np.empty(n, dtype=np.int64)
        cid = world.client
        for s in range(0, n, _MAX_RAYS_PER_BATCH):
            e = min(n, s + _MAX_RAYS_PER_BATCH)
            res = pb.rayTestBatch(frm[s:e].tolist(), to[s:e].tolist(), numThreads=cfg.num_threads,
                                  physicsClientId=cid)
            if len(res) != e - s:
                raise RuntimeError(f"rayTestBatch returned {len(res)} results for {e - s} rays")
            body[s:e] = np.fromiter((r[0] for r in res), dtype=np.int64, count=e - s)
            fraction[s:e] = np.fromiter((r[2] for r in res), dtype=float, count=e - s)
        rng_m = np.where(body >= 0, fraction * cfg.max_range_m, np.inf)
        b = np.clip(body, 0, len(world.semantic_of_body) - 1)
        sem = np.where(body >= 0, world.semantic_of_body[b], int(SemanticClass.SKY)).astype(np.uint8)
        pid = np.where(body >= 0, world.plant_of_body[b], -1).astype(np.int32)
        return rng_m, sem, pid

    def ranges(self, world_T_sensor: np.ndarray, visibility: Optional[BollVisibility] = None
               ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Noise-free range per ray [m] (inf = no return), semantic and plant id, in ray order.

        Ray i is ring ``i // samples_per_ring``, azimuth sample
        ``i % samples_per_ring``. For comparing backends and for tests.
        visibility: which bolls to leave out (default: the scene's snapshot now).
        """
        pose = check_pose("world_T_sensor", world_T_sensor)
        visibility = visibility or self.scene.visibility
        if self.config.backend == "numba":
            return self._cast_numba(pose, visibility)
        return self._cast_pybullet(pose, visibility)

    def scan(self, world_T_sensor: np.ndarray, visibility: Optional[BollVisibility] = None) -> LidarScan:
        """One revolution from the given pose of the 'velodyne' frame (``visibility`` as in ``ranges``)."""
        cfg = self.config
        if cfg.backend == "numba":
            return self._scan_numba(check_pose("world_T_sensor", world_T_sensor), visibility or self.scene.visibility)
        rng_m, sem_all, pid_all = self.ranges(world_T_sensor, visibility)
        hit = np.isfinite(rng_m)
        n = len(rng_m)
        if cfg.noise_std_m > 0.0:
            rng_m = rng_m + self._rng.normal(0.0, cfg.noise_std_m, n)
        with np.errstate(invalid="ignore"):
            keep = hit & (rng_m >= cfg.min_range_m) & (rng_m <= cfg.max_range_m)
        idx = np.nonzero(keep)[0]
        pts = (self._dirs[idx] * rng_m[idx, None]).astype(np.float32)
        sem = sem_all[idx]
        return LidarScan(points=pts, ring=self._ring[idx], intensity=self._reflect[sem].astype(np.float32),
                         azimuth_rad=self._azimuth[idx], semantic=sem.astype(np.uint8),
                         plant_id=pid_all[idx].astype(np.int32))
