"""The static world as the exteroceptive sensors see it.

Why this module exists
----------------------
Cameras and the LiDAR need the farm in a form they can render and ray cast,
separate from the ODE dynamics. ``SensorScene`` holds the farm and builds,
each on first use (so that only the backends in use pay for them):

* ``fast_plants`` / ``fast_bvh``: the flat arrays of the numba backends
  (``sensors.fast.instanced_plants``: instanced plant meshes for the rasteriser;
  ``sensors.fast.bvh``: a bounding volume hierarchy for the ray caster);
* the pybullet structures below (the ray-cast world takes 4-6 s to build
  on the default farm).

* a **ray-cast world** (``ray_world``, ``sensors.ray_world``): an infinite
  ground plane plus, per plant, one body for the plant parts (stem,
  leaves, ...) and one body per boll, made of collision shapes (the models'
  triangle meshes, or their collision primitives).
* **render clients** (``RenderClient``), one per camera, that hold only the
  plants a camera can currently see (frustum and distance culling). The
  TinyRenderer's cost grows with every triangle it is given, whether on
  screen or not, so each camera keeps its own small client and adds/removes
  plant bodies as its view moves.
* the **ground and sky**, which are *not* rendered by pybullet: the ground is
  a plane, so its image is a homography of a procedural soil texture and its
  inverse depth is affine in the pixel coordinates; the sky is a gradient
  over the ray elevation. Computing both with numpy/OpenCV is several times
  cheaper than letting the software rasteriser fill half the image with two
  huge triangles (measured: a bare ground box costs ~65 ms of a 640x480
  TinyRenderer frame). Plants always occlude the ground behind them (both
  lie above z = 0 and the camera is above ground), so the ground/sky layer
  is painted exactly where pybullet drew nothing.

Bolls: every boll is drawn and ray cast as an instance of its own
(``sensors.boll_instances``), so that one that leaves its plant can be left
out. ``set_hidden_bolls`` replaces the immutable ``visibility`` snapshot;
each camera render and LiDAR scan uses the snapshot current when it starts
(or the one it is given), so pipelined sensor jobs stay deterministic.

Frames: world z up, ground at z = 0 [m]; plant-local as in ``farm.model``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, List, Optional, Sequence, Set, Tuple

import cv2
import numpy as np

from cottonsim_common.transforms import yaw_to_quaternion
from cottonsim_common.validation import require_instance
from cottonsim_world.farm.model import Farm, Plant, SemanticClass, TriangleMesh
from cottonsim_world.sensors.boll_instances import SplitFarm
from cottonsim_world.sensors.ray_world import PybulletRayWorld, merge_meshes

if TYPE_CHECKING:                       # pragma: no cover
    from cottonsim_world.sensors.render_client import RenderClient

_COLLISION_SOURCES = ("meshes", "primitives")


def _check_rgb(name: str, value: Sequence[float]) -> None:
    if len(value) != 3 or not all(math.isfinite(v) and 0.0 <= v <= 1.0 for v in value):
        raise ValueError(f"{name} must be 3 values in [0, 1], got {value!r}")


@dataclass(frozen=True)
class SceneConfig:
    """Appearance and ray-cast geometry of the sensor scene.

    Colours are RGB in [0, 1]. The sun direction is given as azimuth
    (counter-clockwise from world +x) and elevation above the horizon [rad];
    it drives pybullet's light for the plants and the flat shading of the
    ground, so datasets can vary the time of day. ``collision_source``
    applies to the pybullet LiDAR backend (the numba backend casts against
    the meshes).
    """

    ground_rgb: Tuple[float, float, float] = (0.47, 0.36, 0.25)   # dry soil brown
    soil_texture: bool = True            # procedural soil noise on the ground
    soil_texture_m_per_px: float = 0.02  # texture resolution on the ground [m/px]
    soil_noise_amplitude: float = 0.22   # relative brightness variation of the soil
    ground_margin_m: float = 15.0        # textured area around the farm's plants [m]
    sky_zenith_rgb: Tuple[float, float, float] = (0.33, 0.52, 0.82)
    sky_horizon_rgb: Tuple[float, float, float] = (0.78, 0.85, 0.93)
    sun_azimuth_rad: float = 0.6
    sun_elevation_rad: float = 0.9
    light_rgb: Tuple[float, float, float] = (1.0, 1.0, 1.0)
    ambient_coeff: float = 0.55          # pybullet lightAmbientCoeff
    diffuse_coeff: float = 0.5           # pybullet lightDiffuseCoeff
    specular_coeff: float = 0.05         # pybullet lightSpecularCoeff
    shadows: bool = False                # TinyRenderer shadow map (costs time)
    collision_source: str = "meshes"     # 'meshes' | 'primitives' for ray casting
    seed: int = 0                        # soil texture noise

    def __post_init__(self) -> None:
        for name in ("ground_rgb", "sky_zenith_rgb", "sky_horizon_rgb", "light_rgb"):
            _check_rgb(name, getattr(self, name))
        if not (self.soil_texture_m_per_px > 0.0 and math.isfinite(self.soil_texture_m_per_px)):
            raise ValueError(f"soil_texture_m_per_px must be > 0, got {self.soil_texture_m_per_px}")
        if not (0.0 <= self.soil_noise_amplitude <= 1.0):
            raise ValueError(f"soil_noise_amplitude must be in [0, 1], got {self.soil_noise_amplitude}")
        if not (self.ground_margin_m >= 0.0 and math.isfinite(self.ground_margin_m)):
            raise ValueError(f"ground_margin_m must be >= 0, got {self.ground_margin_m}")
        if not math.isfinite(self.sun_azimuth_rad):
            raise ValueError(f"sun_azimuth_rad must be finite, got {self.sun_azimuth_rad}")
        if not (0.0 < self.sun_elevation_rad <= math.pi / 2):
            raise ValueError(f"sun_elevation_rad must be in (0, pi/2], got {self.sun_elevation_rad}")
        for name in ("ambient_coeff", "diffuse_coeff", "specular_coeff"):
            v = getattr(self, name)
            if not (0.0 <= v <= 2.0):
                raise ValueError(f"{name} must be in [0, 2], got {v}")
        if self.collision_source not in _COLLISION_SOURCES:
            raise ValueError(f"collision_source must be one of {_COLLISION_SOURCES}, "
                             f"got {self.collision_source!r}")

    @property
    def sun_direction(self) -> np.ndarray:
        """Unit vector from the ground towards the sun, world frame."""
        ce = math.cos(self.sun_elevation_rad)
        return np.array([ce * math.cos(self.sun_azimuth_rad), ce * math.sin(self.sun_azimuth_rad),
                         math.sin(self.sun_elevation_rad)])


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class BollVisibility:
    """Which bolls the sensors leave out: one immutable snapshot (``SensorScene.set_hidden_bolls``).

    revision: the label it was set with; hidden (B,) bool per boll id;
    triangle_hidden (T,) uint8 per triangle of ``SensorScene.fast_bvh`` in
    the tree's (sorted) order (1 = a hidden boll's; what the numba LiDAR
    skips, reading it in step with the triangles), empty until the tree exists.
    """

    revision: int
    hidden: np.ndarray
    triangle_hidden: np.ndarray


def check_pose(name: str, pose: np.ndarray) -> np.ndarray:
    """Validate a 4x4 rigid transform; return it as float64 (raises ValueError)."""
    m = np.asarray(pose, dtype=float)
    if m.shape != (4, 4):
        raise ValueError(f"{name} must be a 4x4 matrix, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ValueError(f"{name} contains NaN or inf")
    r = m[:3, :3]
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-4) or np.linalg.det(r) < 0.0:
        raise ValueError(f"{name} rotation part is not a proper rotation matrix")
    return m


def _validate_model(plant: Plant) -> None:
    for name, mesh in plant.model.meshes.items():
        v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        if v.ndim != 2 or v.shape[1] != 3 or not np.all(np.isfinite(v)):
            raise ValueError(f"plant {plant.plant_id} mesh {name!r}: vertices must be finite (N, 3)")
        if f.ndim != 2 or f.shape[1] != 3 or (f.size and (f.min() < 0 or f.max() >= len(v))):
            raise ValueError(f"plant {plant.plant_id} mesh {name!r}: faces must be (M, 3) indices < {len(v)}")


class SensorScene:
    """The farm's static geometry for rendering and ray casting.

    Build once per farm: ``scene = SensorScene(farm, SceneConfig())``, then
    hand it to ``CameraModel`` and ``Vlp16Model``. ``close()`` frees the
    pybullet clients and the numba arrays (also done by the context
    manager); a closed scene raises RuntimeError when a sensor needs it.
    """

    def __init__(self, farm: Farm, config: SceneConfig = SceneConfig()) -> None:
        require_instance("config", config, SceneConfig)
        if not hasattr(farm, "plants"):
            raise ValueError("farm must be a farm.model.Farm (it has no 'plants')")
        self.farm = farm
        self.config = config
        for plant in farm.plants:
            _validate_model(plant)
        names: List[str] = []
        for plant in farm.plants:
            for name in plant.model.meshes:
                if name not in names:
                    names.append(name)
        self.material_names: Tuple[str, ...] = tuple(names)
        # link index + 1 -> semantic class (0 = base, which has no visual)
        lut = np.full(len(names) + 1, int(SemanticClass.PLANT), dtype=np.uint8)
        for i, name in enumerate(names):
            sem = next(int(p.model.meshes[name].semantic) for p in farm.plants if name in p.model.meshes)
            lut[i + 1] = sem
        self.link_semantic_lut = lut
        self._bounding_spheres = self._plant_bounds()
        self._render_clients: List["RenderClient"] = []
        self._build_soil_texture()
        # built on first use: only the backends in use pay for their structures
        self.split = SplitFarm(farm.plants)
        self._visibility = BollVisibility(0, _read_only(np.zeros(self.split.boll_total, bool)),
                                          _read_only(np.zeros(0, np.uint8)))
        self._ray_world: Optional[PybulletRayWorld] = None
        self._fast_plants = None
        self._fast_bvh = None
        self._closed = False

    # ------------------------------------------------------ lazily built worlds
    def _require_open(self) -> None:
        if self._closed:
            raise RuntimeError("SensorScene is closed")

    @property
    def ray_world(self) -> PybulletRayWorld:
        """The pybullet ray-cast world (``sensors.ray_world``; built on first use, 4-6 s)."""
        self._require_open()
        if self._ray_world is None:
            self._ray_world = PybulletRayWorld(self.split, self.config.collision_source)
        return self._ray_world

    @property
    def ray_client(self) -> int:
        """pybullet client of ``ray_world``: ground plane, plant and boll collision shapes."""
        return self.ray_world.client

    # ------------------------------------------------------------ boll visibility
    @property
    def visibility(self) -> "BollVisibility":
        """The bolls the sensors leave out now: an immutable snapshot (``set_hidden_bolls`` replaces it)."""
        return self._visibility

    def set_hidden_bolls(self, hidden: np.ndarray, revision: int = 0) -> "BollVisibility":
        """Hide the bolls ``hidden`` (B,) bool marks (boll ids as ``farm.bolls.BollField``), show the rest.

        Takes effect for every render and scan that starts afterwards (a sensor
        job given an older snapshot keeps it). ``revision`` labels the snapshot
        (the BollField's). Returns the new snapshot.
        """
        mask = np.asarray(hidden)
        if mask.shape != (self.split.boll_total,) or mask.dtype != bool:
            raise ValueError(f"hidden must be a bool array of shape ({self.split.boll_total},), one per boll, "
                             f"got {mask.dtype} {mask.shape}")
        mask = _read_only(mask.copy())
        self._visibility = BollVisibility(int(revision), mask, self.triangle_mask(mask))
        return self._visibility

    def triangle_mask(self, hidden: np.ndarray) -> np.ndarray:
        """``BollVisibility.triangle_hidden`` of ``hidden`` (empty while the LiDAR's tree is not built)."""
        if self._fast_bvh is None:
            return _read_only(np.zeros(0, np.uint8))
        inst = self._fast_plants
        by_id = np.zeros(inst.triangle_count, np.uint8)       # per full-detail global triangle id
        p = self.split.plant_count
        for j in np.nonzero(hidden)[0]:
            first = int(inst.plant_gbase[p + j])
            by_id[first:first + int(inst.model_fcount[inst.plant_model[p + j]])] = 1
        return _read_only(np.ascontiguousarray(by_id[self._fast_bvh.tri_id]))

    def visible_bolls(self, plant_index: np.ndarray, hidden: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Boll ids on the plants ``plant_index`` (n,) not marked in ``hidden``, and each one's position in
        ``plant_index``."""
        ids, owner = self.split.bolls_of(plant_index)
        keep = ~hidden[ids]
        return ids[keep], owner[keep]

    @property
    def fast_plants(self):
        """``fast.instanced_plants.InstancedPlants`` of the farm (numba camera; built on first use)."""
        self._require_open()
        if self._fast_plants is None:
            from cottonsim_world.sensors.fast.instanced_plants import InstancedPlants
            cfg = self.config
            self._fast_plants = InstancedPlants(self.split.instances, cfg.sun_direction, cfg.ambient_coeff,
                                                cfg.diffuse_coeff, cfg.light_rgb)
        return self._fast_plants

    @property
    def fast_bvh(self):
        """``fast.bvh.TriangleBVH`` of the farm's meshes (numba LiDAR; built on first use)."""
        self._require_open()
        if self._fast_bvh is None:
            from cottonsim_world.sensors.fast.bvh import TriangleBVH
            triangles, ids = self.fast_plants.world_triangles(one_sided_duplicates=True)
            self._fast_bvh = TriangleBVH(triangles, ids)
            v = self._visibility
            self._visibility = BollVisibility(v.revision, v.hidden, self.triangle_mask(v.hidden))
        return self._fast_bvh

    def background_layer(self) -> Tuple[np.ndarray, float, float, float, float, np.ndarray]:
        """What ``ground_and_sky`` paints, for the numba camera.

        Returns (soil texture (h, w, 3) uint8 RGB, world x and y [m] of the
        centre of texture pixel (0, 0), texture resolution along x and y
        [m/px], sky colour lookup table (256, 3) uint8 indexed by
        255 * sin(ray elevation)).
        """
        m = self._world_from_tex
        return self.soil_texture, float(m[0, 2]), float(m[1, 2]), float(m[0, 0]), float(m[1, 1]), self._sky_lut

    # ------------------------------------------------------------------ geometry
    def _plant_bounds(self) -> np.ndarray:
        """(P, 4): bounding sphere centre x, y, z and radius per plant [m]."""
        out = np.zeros((len(self.farm.plants), 4))
        for i, plant in enumerate(self.farm.plants):
            v, _ = merge_meshes(list(plant.model.meshes.values()))
            if len(v) == 0:
                out[i] = (plant.x_m, plant.y_m, 0.0, 0.0)
                continue
            lo, hi = v.min(axis=0), v.max(axis=0)
            c_local = 0.5 * (lo + hi)
            r = float(np.max(np.linalg.norm(v - c_local, axis=1)))
            c, s = math.cos(plant.yaw_rad), math.sin(plant.yaw_rad)
            out[i] = (plant.x_m + c * c_local[0] - s * c_local[1],
                      plant.y_m + s * c_local[0] + c * c_local[1], c_local[2], r)
        return out

    def plants_in_view(self, world_T_optical: np.ndarray, tan_half_h: float, tan_half_v: float,
                       max_distance_m: float) -> Set[int]:
        """Indices of the plants whose bounding sphere touches a view frustum.

        The frustum is that of a camera in the optical convention (z forward,
        x right, y down) with the given half-angle tangents, cut at
        ``max_distance_m`` along z. Conservative: a sphere is kept unless it
        lies entirely outside one of the planes.
        """
        index, _ = self.plants_in_view_depth(world_T_optical, tan_half_h, tan_half_v, max_distance_m)
        return set(index.tolist())

    def plants_in_view_depth(self, world_T_optical: np.ndarray, tan_half_h: float, tan_half_v: float,
                             max_distance_m: float) -> Tuple[np.ndarray, np.ndarray]:
        """Like ``plants_in_view``, as arrays: ascending plant indices (n,) int64 and the
        optical-axis depth of each one's bounding sphere's nearest point (n,) float64 [m]
        (centre depth minus radius; <= 0 when the camera is inside the sphere's slab)."""
        if len(self._bounding_spheres) == 0:
            return np.zeros(0, np.int64), np.zeros(0)
        pose = check_pose("world_T_optical", world_T_optical)
        r_wo, t_wo = pose[:3, :3], pose[:3, 3]
        c = (self._bounding_spheres[:, :3] - t_wo) @ r_wo        # centres in the optical frame
        rad = self._bounding_spheres[:, 3]
        x, y, z = c[:, 0], c[:, 1], c[:, 2]
        keep = (z > -rad) & (z < max_distance_m + rad)
        # side planes through the origin: |x| <= z * tan  <=>  (x - z tan) / sqrt(1 + tan^2) <= r
        nh, nv = math.sqrt(1 + tan_half_h ** 2), math.sqrt(1 + tan_half_v ** 2)
        keep &= (x - z * tan_half_h) / nh <= rad
        keep &= (-x - z * tan_half_h) / nh <= rad
        keep &= (y - z * tan_half_v) / nv <= rad
        keep &= (-y - z * tan_half_v) / nv <= rad
        index = np.nonzero(keep)[0].astype(np.int64)
        return index, z[index] - rad[index]

    def new_render_client(self, renderer: str = "tiny") -> "RenderClient":
        """A fresh, empty render client (one per camera)."""
        self._require_open()
        from cottonsim_world.sensors.render_client import RenderClient     # local: it refers back to the scene

        rc = RenderClient(self, renderer)
        self._render_clients.append(rc)
        return rc

    # ------------------------------------------------------------ ground & sky
    def _build_soil_texture(self) -> None:
        cfg = self.config
        pts = self.farm.plant_positions()
        if len(pts):
            lo, hi = pts.min(axis=0) - cfg.ground_margin_m, pts.max(axis=0) + cfg.ground_margin_m
        else:
            lo, hi = np.array([-cfg.ground_margin_m] * 2), np.array([cfg.ground_margin_m] * 2)
        res = cfg.soil_texture_m_per_px
        w = int(min(4096, math.ceil((hi[0] - lo[0]) / res)))
        h = int(min(4096, math.ceil((hi[1] - lo[1]) / res)))
        self._tex_origin = lo
        self._tex_res = ((hi[0] - lo[0]) / w, (hi[1] - lo[1]) / h)   # [m/px] along x, y
        base = np.array(cfg.ground_rgb, dtype=np.float32)
        if cfg.soil_texture and cfg.soil_noise_amplitude > 0.0:
            rng = np.random.default_rng(cfg.seed)
            shade = np.zeros((h, w), np.float32)
            for cells, weight in ((8, 0.45), (64, 0.3), (512, 0.15)):   # clods .. grains
                small = rng.standard_normal((max(2, h * cells // max(h, w)), cells)).astype(np.float32)
                shade += weight * cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
            shade += 0.1 * rng.standard_normal((h, w)).astype(np.float32)
            shade *= cfg.soil_noise_amplitude / max(1e-6, float(shade.std()))
            tex = base[None, None, :] * (1.0 + shade[..., None])
        else:
            tex = np.broadcast_to(base, (h, w, 3)).copy()
        # flat shading of a z-up plane under the scene's light
        light = cfg.ambient_coeff + cfg.diffuse_coeff * max(0.0, math.sin(cfg.sun_elevation_rad))
        tex = tex * light * np.array(cfg.light_rgb, np.float32)
        self.soil_texture = np.clip(tex * 255.0, 0, 255).astype(np.uint8)      # (h, w, 3) RGB
        # texture pixel (col, row) -> world (x, y, 1)
        self._world_from_tex = np.array([[self._tex_res[0], 0.0, lo[0] + 0.5 * self._tex_res[0]],
                                         [0.0, self._tex_res[1], lo[1] + 0.5 * self._tex_res[1]],
                                         [0.0, 0.0, 1.0]])
        zen = np.array(cfg.sky_zenith_rgb, np.float32)
        hor = np.array(cfg.sky_horizon_rgb, np.float32)
        t = np.linspace(0.0, 1.0, 256, dtype=np.float32) ** 0.6
        self._sky_lut = np.clip(255.0 * (hor[None] + (zen - hor)[None] * t[:, None]), 0, 255).astype(np.uint8)

    def ground_and_sky(self, world_T_optical: np.ndarray, K: np.ndarray, width: int, height: int,
                       ray_norm: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Background layer seen by a pinhole camera, for every pixel.

        Returns rgb (H, W, 3) uint8, depth (H, W) float32 metric depth along
        the optical z axis (inf where the ray does not hit the ground) and
        semantic (H, W) uint8 (GROUND or SKY). ``ray_norm`` is the (H, W)
        length of the optical ray (u - cx)/fx, (v - cy)/fy, 1.
        """
        pose = check_pose("world_T_optical", world_T_optical)
        r, t = pose[:3, :3], pose[:3, 3]
        k_inv = np.linalg.inv(K)
        # world z-component of the ray K^-1 (u, v, 1) is affine in (u, v): a_u u + a_v v + a_0
        a = r[2, :] @ k_inv
        u = np.arange(width, dtype=np.float32)[None, :]
        v = np.arange(height, dtype=np.float32)[:, None]
        dz = (a[0] * u + a[1] * v + a[2]).astype(np.float32)
        hits = dz < -1e-9
        cam_h = float(t[2])
        with np.errstate(divide="ignore", invalid="ignore"):
            depth = np.where(hits, -cam_h / dz, np.inf).astype(np.float32)
        if cam_h <= 0.0:
            depth[:] = np.inf
            hits[:] = False
        # ground colour: homography texture -> image for the plane z = 0
        cam_T_world = np.linalg.inv(pose)
        h_img_world = K @ cam_T_world[:3, [0, 1, 3]]
        h_img_tex = h_img_world @ self._world_from_tex
        ground = cv2.warpPerspective(self.soil_texture, h_img_tex, (width, height),
                                     flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        # sky: gradient on the sine of the ray elevation
        sin_el = np.clip(dz / ray_norm, 0.0, 1.0)
        sky = self._sky_lut[(sin_el * 255.0).astype(np.intp)]
        rgb = np.where(hits[..., None], ground, sky)
        semantic = np.where(hits, np.uint8(SemanticClass.GROUND), np.uint8(SemanticClass.SKY)).astype(np.uint8)
        return rgb, depth, semantic

    # ----------------------------------------------------------------- cleanup
    def close(self) -> None:
        for rc in self._render_clients:
            rc.close()
        self._render_clients = []
        if self._ray_world is not None:
            self._ray_world.close()
        self._ray_world = None
        self._fast_plants = None
        self._fast_bvh = None
        self._closed = True

    def __enter__(self) -> "SensorScene":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# ---------------------------------------------------------------- stand-ins
