"""Procedural cotton plant: meshes for rendering, primitives for collision.

Why: the original CottonSim used hand-made Collada plants that are not in its
repository. This module grows a plausible cotton plant from a random
generator instead, so every farm can be regenerated, varied and tested.

What a plant looks like (plant-local frame: stem foot at the origin, z up):

* a slightly wavy, tapered main stem up to ~93 % of the plant height;
* fruiting branches from ``canopy_base_m`` upwards, spiralling round the stem
  at the golden angle, longest in the middle of the canopy (the bush is
  densest and widest half-way up, narrow at the top);
* broad, palmately lobed (3-5 lobes), slightly cupped, dark green leaves at
  the branch nodes and on top, plus a few brown dead leaves low down;
* white, lumpy bolls (4-5 locks) hanging below nodes on short stalks, each on
  a brown star-shaped bract.

Leaves and bracts are two-sided (each face twice, once per winding) because
pybullet's TinyRenderer culls back faces. Everything is clipped to the
nominal size: all vertices satisfy ``hypot(x, y) <= width_m / 2`` and
``0 <= z <= height_m``.

Output: ``farm.model.PlantModel`` with meshes 'stem', 'leaf' (absent when
defoliated), 'dead_leaf' (dead leaves + bracts), 'boll'; collision primitives
'stem' (cylinder) and 'canopy_low' / 'canopy_mid' / 'canopy_top' (vertical
cylinders covering branches and leaves, radius <= width_m / 2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from cottonsim_common.validation import require_instance, require_positive
from cottonsim_world.farm.model import PlantModel, PlantSkeleton, Primitive, SemanticClass, TriangleMesh

GOLDEN_ANGLE_RAD = math.pi * (3.0 - math.sqrt(5.0))   # ~137.5 deg, cotton's spiral phyllotaxy

# Base colours (rgba 0..1), matched by eye to the original Gazebo images.
STEM_RGBA = (0.42, 0.47, 0.27, 1.0)
DRY_STEM_RGBA = (0.42, 0.33, 0.22, 1.0)     # defoliated plants: dried, brown stems
LEAF_RGBA = (0.20, 0.45, 0.13, 1.0)
DEAD_LEAF_RGBA = (0.45, 0.32, 0.16, 1.0)
BOLL_RGBA = (0.96, 0.96, 0.94, 1.0)


@dataclass(frozen=True)
class CottonPlantConfig:
    """Shape parameters of one procedural cotton plant.

    height_m, width_m: overall size [m]; the geometry is clipped to it.
    boll_count: number of open bolls (>= 0).
    growth_stage: 'cutout' (leafy) or 'defoliated' (no green leaves, more
        dead leaves, bolls bigger and more exposed).
    detail: 'high' (~1,500-4,000 triangles) or 'low' (a few hundred).
    canopy_base_m: height of the lowest branch [m].
    boll_radius_m: (min, max) radius of a boll [m] (a boll is 4-6 cm wide).
    leaf_radius_m: (min, max) reach of a leaf blade from its base [m].
    branch_count: fruiting branches; None = 14 (high) / 7 (low).
    dead_leaf_count: None = 4 (cutout) / 8 (defoliated).
    """

    height_m: float = 1.0
    width_m: float = 0.7
    boll_count: int = 12
    growth_stage: str = "cutout"
    detail: str = "high"
    canopy_base_m: float = 0.15
    boll_radius_m: Tuple[float, float] = (0.022, 0.03)
    leaf_radius_m: Tuple[float, float] = (0.065, 0.10)
    branch_count: Optional[int] = None
    dead_leaf_count: Optional[int] = None

    def __post_init__(self) -> None:
        for name in ("height_m", "width_m", "canopy_base_m"):
            require_positive(name, getattr(self, name))
        if self.canopy_base_m >= 0.6 * self.height_m:
            raise ValueError(f"canopy_base_m={self.canopy_base_m} must be below 60 % of height_m={self.height_m}")
        if isinstance(self.boll_count, bool) or not isinstance(self.boll_count, (int, np.integer)) or self.boll_count < 0:
            raise ValueError(f"boll_count must be an integer >= 0, got {self.boll_count!r}")
        if self.growth_stage not in ("cutout", "defoliated"):
            raise ValueError(f"growth_stage must be 'cutout' or 'defoliated', got {self.growth_stage!r}")
        if self.detail not in ("high", "low"):
            raise ValueError(f"detail must be 'high' or 'low', got {self.detail!r}")
        for name in ("boll_radius_m", "leaf_radius_m"):
            lo_hi = getattr(self, name)
            if len(lo_hi) != 2 or not (0 < lo_hi[0] <= lo_hi[1]) or lo_hi[1] > 0.25 * self.width_m:
                raise ValueError(f"{name} must be (min, max) with 0 < min <= max <= width_m / 4, got {lo_hi!r}")
        for name in ("branch_count", "dead_leaf_count"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0 or v > 200):
                raise ValueError(f"{name} must be None or an integer in [0, 200], got {v!r}")


class _MeshBuilder:
    """Accumulates vertices and faces of one material."""

    def __init__(self) -> None:
        self._verts: List[np.ndarray] = []
        self._faces: List[np.ndarray] = []
        self._count = 0

    def add(self, verts: np.ndarray, faces: np.ndarray) -> None:
        self._verts.append(np.asarray(verts, dtype=float))
        self._faces.append(np.asarray(faces, dtype=np.int64) + self._count)
        self._count += len(verts)

    @property
    def empty(self) -> bool:
        return self._count == 0

    def arrays(self) -> Tuple[np.ndarray, np.ndarray]:
        if self.empty:
            return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
        return np.concatenate(self._verts), np.concatenate(self._faces)


# ----------------------------------------------------------------- primitives
def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > 1e-12 else v


def _tube(points: np.ndarray, radii: Sequence[float], sides: int) -> Tuple[np.ndarray, np.ndarray]:
    """Open tapered tube along a polyline; outward-facing triangles."""
    points = np.asarray(points, dtype=float)
    n = len(points)
    verts = np.empty((n * sides, 3))
    ang = np.arange(sides) * (2.0 * math.pi / sides)
    for k in range(n):
        t = _unit(points[min(k + 1, n - 1)] - points[max(k - 1, 0)])
        ref = np.array([1.0, 0.0, 0.0]) if abs(t[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        u = _unit(np.cross(t, ref))
        v = np.cross(t, u)
        verts[k * sides:(k + 1) * sides] = (points[k] + radii[k] * (np.outer(np.cos(ang), u) + np.outer(np.sin(ang), v)))
    faces = []
    for k in range(n - 1):
        for j in range(sides):
            a, b = k * sides + j, k * sides + (j + 1) % sides
            c, d = a + sides, b + sides
            faces.append((a, b, d))
            faces.append((a, d, c))
    return verts, np.array(faces, dtype=np.int64)


def _two_sided(faces: np.ndarray) -> np.ndarray:
    return np.concatenate([faces, faces[:, ::-1]])


def _fan(n_boundary: int, closed: bool) -> np.ndarray:
    """Triangles of a fan: vertex 0 is the hub, 1..n the boundary."""
    m = n_boundary if closed else n_boundary - 1
    return np.array([(0, 1 + j, 1 + (j + 1) % n_boundary) for j in range(m)], dtype=np.int64)


def _leaf_frame(azimuth: float, pitch: float, roll: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Axes (u along the midrib, v across, n up) of a leaf blade.

    azimuth: direction of the midrib about z; pitch: tip down [rad]; roll
    about the midrib [rad].
    """
    u0 = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
    v0 = np.array([-math.sin(azimuth), math.cos(azimuth), 0.0])
    n0 = np.array([0.0, 0.0, 1.0])
    u = math.cos(pitch) * u0 - math.sin(pitch) * n0
    n1 = math.sin(pitch) * u0 + math.cos(pitch) * n0
    v = math.cos(roll) * v0 + math.sin(roll) * n1
    n = -math.sin(roll) * v0 + math.cos(roll) * n1
    return u, v, n


def _leaf(base: np.ndarray, radius: float, azimuth: float, pitch: float, roll: float,
          lobes: int, detail: str, rng: np.random.Generator) -> Tuple[np.ndarray, np.ndarray]:
    """A palmately lobed, cupped leaf blade whose base (petiole end) is ``base``."""
    if detail == "high":
        # boundary points at lobe tips (even k) and sinuses (odd k)
        theta = np.arange(-6, 7) * 0.45
        tip = (np.arange(-6, 7) % 2) == 0
        sinus_depth = 0.55 if lobes >= 5 else 0.65
        lobe = np.where(tip, 1.0, sinus_depth)
        if lobes < 5:   # 3-lobed: the side-back lobes (|k| = 4) are weak
            lobe = np.where(np.abs(np.arange(-6, 7)) >= 4, lobe * 0.75, lobe)
    else:
        theta = np.arange(-3, 4) * 0.9
        lobe = np.ones_like(theta)
    envelope = np.cos(theta / 2.4) ** 1.2
    r = radius * envelope * lobe * (1.0 + 0.06 * rng.standard_normal(theta.shape))
    # blade centre sits ahead of the petiole end: shift the hub forward
    uu = r * np.cos(theta) + 0.25 * radius
    vv = r * np.sin(theta)
    ww = 0.30 * vv ** 2 / radius - 0.25 * np.clip(uu, 0, None) ** 2 / radius
    hub = np.array([[0.25 * radius, 0.0, -0.03 * radius]])
    local = np.concatenate([hub, np.stack([uu, vv, ww], axis=1)])
    u, v, n = _leaf_frame(azimuth, pitch, roll)
    verts = base + local[:, :1] * u + local[:, 1:2] * v + local[:, 2:3] * n
    return verts, _two_sided(_fan(len(theta), closed=False))


def _leaf_sphere(base: np.ndarray, radius: float, azimuth: float, pitch: float,
                 roll: float) -> Tuple[np.ndarray, float]:
    """Centre and radius of a sphere round the blade ``_leaf`` draws (its midrib spans about
    -0.1 .. 1.25 radius from the base, its width about 1.6 radius)."""
    u, _v, _n = _leaf_frame(azimuth, pitch, roll)
    return base + 0.55 * radius * u, 0.7 * radius


def _boll(centre: np.ndarray, radius: float, detail: str, rng: np.random.Generator) -> Tuple[np.ndarray, np.ndarray]:
    """A lumpy, slightly squashed sphere: the fluffy locks of an open boll."""
    n_lon, n_lat = (8, 4) if detail == "high" else (4, 2)
    locks = 4 if rng.random() < 0.5 else 5
    phase = rng.uniform(0, 2 * math.pi)
    lon = np.arange(n_lon) * (2 * math.pi / n_lon) + phase
    lat = np.arange(1, n_lat) * (math.pi / n_lat)           # rings, poles excluded
    L, A = np.meshgrid(lon, lat)                             # (n_lat-1, n_lon)
    bump = 1.0 + 0.22 * np.cos(locks * (L - phase)) * np.sin(A) ** 2 + 0.08 * rng.standard_normal(L.shape)
    rr = radius * bump
    ring = np.stack([rr * np.sin(A) * np.cos(L), rr * np.sin(A) * np.sin(L), 0.85 * rr * np.cos(A)], axis=-1).reshape(-1, 3)
    top = np.array([[0.0, 0.0, 0.80 * radius]])
    bottom = np.array([[0.0, 0.0, -0.85 * radius]])
    verts = centre + np.concatenate([top, ring, bottom])
    # counter-clockwise seen from outside (longitude grows counter-clockwise seen from above), so that a
    # renderer that culls back faces draws the near side of the boll, not the inside of its far side
    faces = []
    n_rings = n_lat - 1
    for j in range(n_lon):                                   # top cap
        faces.append((0, 1 + j, 1 + (j + 1) % n_lon))
    for i in range(n_rings - 1):
        for j in range(n_lon):
            a = 1 + i * n_lon + j
            b = 1 + i * n_lon + (j + 1) % n_lon
            c, d = a + n_lon, b + n_lon
            faces.append((a, c, d))
            faces.append((a, d, b))
    last = 1 + n_rings * n_lon
    base = 1 + (n_rings - 1) * n_lon
    for j in range(n_lon):                                   # bottom cap
        faces.append((last, base + (j + 1) % n_lon, base + j))
    return verts, np.array(faces, dtype=np.int64)


def _bract(centre: np.ndarray, radius: float, rng: np.random.Generator) -> Tuple[np.ndarray, np.ndarray]:
    """A five-pointed, upward-cupped brown star under a boll."""
    k = np.arange(10)
    ang = k * (math.pi / 5) + rng.uniform(0, 2 * math.pi)
    r = np.where(k % 2 == 0, 1.25 * radius, 0.55 * radius)
    ring = np.stack([r * np.cos(ang), r * np.sin(ang), 0.15 * r], axis=1)
    verts = centre + np.concatenate([np.zeros((1, 3)), ring])
    return verts, _two_sided(_fan(10, closed=True))


# ------------------------------------------------------------------ the plant
def build_cotton_plant(config: CottonPlantConfig = CottonPlantConfig(),
                       rng: Union[np.random.Generator, int, None] = 0) -> PlantModel:
    """Grow one cotton plant; deterministic for a given seed / Generator state.

    rng: a numpy Generator (consumed) or an integer seed.
    Returns a PlantModel in plant-local coordinates (stem foot at the origin).
    """
    require_instance("config", config, CottonPlantConfig)
    if rng is None or isinstance(rng, (int, np.integer)):
        rng = np.random.default_rng(rng)
    elif not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy Generator or an int seed, got {type(rng).__name__}")

    high = config.detail == "high"
    H, W = float(config.height_m), float(config.width_m)
    leafy = config.growth_stage == "cutout"
    stem_b, leaf_b, dead_b, boll_b = _MeshBuilder(), _MeshBuilder(), _MeshBuilder(), _MeshBuilder()

    # --- main stem: a slightly wavy polyline, tapering towards the top
    top_z = 0.93 * H
    n_seg = 4 if high else 2
    zs = np.linspace(0.0, top_z, n_seg + 1)
    wobble = np.zeros((n_seg + 1, 2))
    wobble[1:] = np.cumsum(rng.normal(0.0, 0.008 * H, size=(n_seg, 2)), axis=0)
    stem_pts = np.column_stack([wobble, zs])
    stem_base_r = 0.010 * H
    stem_r = np.linspace(stem_base_r, 0.003 * H, n_seg + 1)
    stem_b.add(*_tube(stem_pts, stem_r, 6 if high else 4))
    woody: Dict[str, List] = {"stem": [(stem_pts[k], stem_pts[k + 1], stem_r[k]) for k in range(n_seg)],
                              "branch": []}
    leaf_spheres: List[Tuple[np.ndarray, float]] = []

    def stem_at(z: float) -> np.ndarray:
        return np.array([np.interp(z, zs, stem_pts[:, 0]), np.interp(z, zs, stem_pts[:, 1]), z])

    # --- fruiting branches spiralling up the stem
    n_branch = config.branch_count if config.branch_count is not None else (16 if high else 8)
    leaf_r_lo, leaf_r_hi = config.leaf_radius_m
    base_z, crown_z = config.canopy_base_m, 0.85 * H
    reach_max = max(0.5 * W - leaf_r_hi, 0.3 * W)
    nodes: List[Tuple[np.ndarray, float, float]] = []        # (position, azimuth, relative height t)
    az0 = rng.uniform(0, 2 * math.pi)
    for i in range(n_branch):
        t = (i + rng.uniform(-0.3, 0.3)) / max(n_branch - 1, 1)
        t = float(np.clip(t, 0.0, 1.0))
        z = base_z + t * (crown_z - base_z)
        az = az0 + i * GOLDEN_ANGLE_RAD + rng.normal(0, 0.15)
        profile = (0.55 + 0.45 * math.sin(math.pi * t)) * (1.0 - 0.45 * t * t)
        length = reach_max * profile * rng.uniform(0.85, 1.05)
        rise = math.tan(rng.uniform(math.radians(20), math.radians(40)))
        d = np.array([math.cos(az), math.sin(az), 0.0])
        p0 = stem_at(z)
        p1 = p0 + d * 0.5 * length + np.array([0, 0, 0.5 * length * rise])
        p2 = p0 + d * length + np.array([0, 0, 0.75 * length * rise])
        pts = np.array([p0, p1, p2]) if high else np.array([p0, p2])
        radii = np.linspace(0.006 * H, 0.0025 * H, len(pts))
        stem_b.add(*_tube(pts, radii, 4 if high else 3))
        woody["branch"].extend((pts[k], pts[k + 1], radii[k]) for k in range(len(pts) - 1))
        for frac in ((0.4, 0.75, 1.0) if high else (0.6, 1.0)):
            seg = np.clip(frac * 2.0, 0, 2) if high else frac
            if high:
                q = p0 + (p1 - p0) * min(seg, 1.0) + (p2 - p1) * max(seg - 1.0, 0.0)
            else:
                q = p0 + (p2 - p0) * frac
            nodes.append((q, az, t))

    # --- green leaves: one per node, a few along the stem, a cluster on top
    if leafy:
        leaf_sites: List[Tuple[np.ndarray, float, float]] = []
        for q, az, t in nodes:
            leaf_sites.append((q, az + rng.normal(0, 0.6), t))
            if high and rng.random() < 0.45:                  # a second, opposite leaf at some nodes
                leaf_sites.append((q, az + math.pi + rng.normal(0, 0.6), t))
        n_stem_leaves = 6 if high else 2
        for k in range(n_stem_leaves):
            t = rng.uniform(0.1, 0.9)
            leaf_sites.append((stem_at(base_z + t * (crown_z - base_z)), rng.uniform(0, 2 * math.pi), t))
        for k in range(5 if high else 3):                    # terminal cluster
            leaf_sites.append((stem_at(top_z), az0 + k * 2 * math.pi / 5 + rng.normal(0, 0.3), 1.0))
        for q, az, t in leaf_sites:
            radius = rng.uniform(leaf_r_lo, leaf_r_hi) * (1.0 - 0.3 * t)
            petiole = 0.3 * radius
            base = q + np.array([math.cos(az) * petiole, math.sin(az) * petiole, 0.4 * petiole])
            pitch = rng.uniform(math.radians(-15), math.radians(40))
            roll = rng.normal(0.0, math.radians(20))
            lobes = 5 if rng.random() < 0.5 else 3
            leaf_b.add(*_leaf(base, radius, az, pitch, roll, lobes, config.detail, rng))
            leaf_spheres.append(_leaf_sphere(base, radius, az, pitch, roll))

    # --- dead leaves, low on the plant (more of them when defoliated)
    n_dead = config.dead_leaf_count if config.dead_leaf_count is not None else (4 if leafy else 8)
    if not high:
        n_dead = min(n_dead, 3)
    low_nodes = [nd for nd in nodes if nd[2] <= 0.5] or nodes
    for k in range(n_dead):
        if not low_nodes:
            break
        q, az, t = low_nodes[int(rng.integers(len(low_nodes)))]
        radius = rng.uniform(leaf_r_lo, leaf_r_hi) * 0.75
        az = az + rng.normal(0, 0.8)
        pitch = rng.uniform(math.radians(35), math.radians(70))   # limp, hanging
        roll = rng.normal(0, 0.4)
        dead_b.add(*_leaf(q, radius, az, pitch, roll, 3, config.detail, rng))
        leaf_spheres.append(_leaf_sphere(q, radius, az, pitch, roll))

    # --- bolls on the nodes (bottom-up bias: lower bolls open first)
    b_lo, b_hi = config.boll_radius_m
    boll_scale = 1.0 if leafy else 1.12
    candidates = [nd for nd in nodes] + [(stem_at(top_z), az0, 1.0)]
    weights = np.array([1.3 - 0.6 * t for _, _, t in candidates])
    weights /= weights.sum()
    n_bolls = int(config.boll_count)
    if n_bolls <= len(candidates):
        chosen = list(rng.choice(len(candidates), size=n_bolls, replace=False, p=weights))
    else:
        chosen = list(range(len(candidates))) + list(rng.choice(len(candidates), size=n_bolls - len(candidates), p=weights))
    seen: Dict[int, int] = {}
    centres, radii_b = [], []
    for idx in chosen:
        q, az, t = candidates[int(idx)]
        repeat = seen.get(int(idx), 0)
        seen[int(idx)] = repeat + 1
        rb = rng.uniform(b_lo, b_hi) * boll_scale
        side = az + (rng.uniform(-1.2, 1.2) if repeat == 0 else rng.uniform(1.5, 4.7))
        out = np.array([math.cos(side), math.sin(side), 0.0])
        hang = -1.3 * rb if leafy else 0.6 * rb                 # exposed bolls point up
        c = q + out * (0.8 * rb) + np.array([0.0, 0.0, hang])
        centres.append(c)
        radii_b.append(rb)
        boll_b.add(*_boll(c, rb, config.detail, rng))
        if high:
            dead_b.add(*_bract(c + np.array([0, 0, -0.8 * rb]), rb, rng))
            stem_b.add(*_tube(np.array([q, c + np.array([0, 0, -0.5 * rb])]), [0.002 * H, 0.0015 * H], 3))

    # --- clip everything to the nominal envelope (radius W/2, height H)
    builders = {"stem": stem_b, "leaf": leaf_b, "dead_leaf": dead_b, "boll": boll_b}
    arrays = {name: b.arrays() for name, b in builders.items()}
    all_v = np.concatenate([v for v, _ in arrays.values()])
    r_max = float(np.max(np.hypot(all_v[:, 0], all_v[:, 1])))
    z_max = float(np.max(all_v[:, 2]))
    sxy = min(1.0, 0.5 * W / r_max) * (1 - 1e-6) if r_max > 0 else 1.0
    sz = min(1.0, H / z_max) * (1 - 1e-6) if z_max > 0 else 1.0
    scale = np.array([sxy, sxy, sz])
    centres_arr = np.array(centres, dtype=float).reshape(-1, 3) * scale
    radii_arr = np.array(radii_b, dtype=float)

    rgba = {
        "stem": _vary(STEM_RGBA if leafy else DRY_STEM_RGBA, rng, 0.04),
        "leaf": _vary(LEAF_RGBA, rng, 0.05),
        "dead_leaf": _vary(DEAD_LEAF_RGBA, rng, 0.05),
        "boll": _vary(BOLL_RGBA, rng, 0.02),
    }
    meshes: Dict[str, TriangleMesh] = {}
    for name, (v, f) in arrays.items():
        if len(f) == 0:
            continue
        v = v * scale
        v[:, 2] = np.maximum(v[:, 2], 0.0)
        meshes[name] = TriangleMesh(
            vertices=v.astype(np.float32), faces=f.astype(np.int32), rgba=rgba[name],
            semantic=SemanticClass.BOLL if name == "boll" else SemanticClass.PLANT)

    collision = _collision_primitives(meshes, stem_base_r, top_z * sz, base_z * sz, H, W)
    return PlantModel(meshes=meshes, collision=collision, boll_centres=centres_arr,
                      boll_radii=radii_arr, height_m=H, width_m=W,
                      skeleton=_skeleton(woody, leaf_spheres, scale))


def _skeleton(woody: Dict[str, List], leaf_spheres: List[Tuple[np.ndarray, float]],
              scale: np.ndarray) -> PlantSkeleton:
    """The plant's stem and branch segments and leaf spheres, clipped like the meshes (scaled)."""
    def segments(parts):
        start = np.array([a for a, _, _ in parts], dtype=float).reshape(-1, 3) * scale
        end = np.array([b for _, b, _ in parts], dtype=float).reshape(-1, 3) * scale
        return start, end, np.array([r for _, _, r in parts], dtype=float)

    stem, branch = segments(woody["stem"]), segments(woody["branch"])
    leaf_c = np.array([c for c, _ in leaf_spheres], dtype=float).reshape(-1, 3) * scale
    leaf_r = np.array([r for _, r in leaf_spheres], dtype=float) * float(scale[0])
    return PlantSkeleton(*stem, *branch, leaf_c, leaf_r)


def _vary(rgba: Tuple[float, float, float, float], rng: np.random.Generator, amount: float) -> Tuple[float, float, float, float]:
    """Small per-plant colour variation (same brightness change on r, g, b)."""
    k = 1.0 + rng.uniform(-amount, amount)
    return tuple(float(np.clip(c * k, 0.0, 1.0)) for c in rgba[:3]) + (rgba[3],)


def _collision_primitives(meshes: Dict[str, TriangleMesh], stem_r: float, stem_top: float,
                          canopy_base: float, H: float, W: float) -> List[Primitive]:
    """Stem cylinder + three vertical canopy cylinders (low / mid / top band).

    Each band's radius is the 90th percentile of the radial distance of the
    branch, leaf and boll vertices in that band (sparse outliers are left
    out), never more than W/2.
    """
    ident = (0.0, 0.0, 0.0, 1.0)
    prims = [Primitive("cylinder", (0.0, 0.0, stem_top / 2.0), ident, (stem_r, stem_top), "stem")]
    pts = np.concatenate([m.vertices for m in meshes.values()]).astype(float)
    r = np.hypot(pts[:, 0], pts[:, 1])
    z_top = float(pts[:, 2].max())
    edges = np.linspace(canopy_base, z_top, 4)
    for name, z0, z1 in zip(("canopy_low", "canopy_mid", "canopy_top"), edges[:-1], edges[1:]):
        sel = (pts[:, 2] >= z0) & (pts[:, 2] <= z1) & (r > stem_r)
        if np.count_nonzero(sel) < 4:
            continue
        radius = float(min(np.percentile(r[sel], 90), 0.5 * W))
        prims.append(Primitive("cylinder", (0.0, 0.0, 0.5 * (z0 + z1)), ident, (radius, float(z1 - z0)), name))
    return prims
