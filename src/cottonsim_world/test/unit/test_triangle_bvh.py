"""The LiDAR's BVH finds exactly the nearest triangle a brute-force search finds.

The ray caster is exact only if the tree never loses a triangle a ray hits
(a box that does not contain its triangles, a subtree skipped too early).
Its hits on random rays through a small generated farm (from inside a lane,
from the headland and from anywhere above the ground) are compared with a
brute-force test of every triangle, done in numpy with the same float32
corners and the same float64 formulas, so the ranges must agree to the bit;
two triangles at exactly the same distance (a shared edge) may trade places.
The tree's structure is checked too: every triangle in exactly one leaf,
every box around what it holds.
"""
import math

import numpy as np
import pytest

from cottonsim_world.farm.generator import FarmConfig, generate_farm
from cottonsim_world.sensors.fast.bvh import BOX_PAD_M, TriangleBVH
from cottonsim_world.sensors.fast.raycast import HIT_GROUND, HIT_NONE, cast_rays
from cottonsim_world.sensors.scene import SensorScene


@pytest.fixture(scope="module")
def farm_bvh():
    farm = generate_farm(FarmConfig(rows=3, plants_per_row=5, plant_variants=2, seed=7))
    with SensorScene(farm) as scene:
        tris, ids = scene.fast_plants.world_triangles(one_sided_duplicates=True)
        yield farm, tris, ids, TriangleBVH(tris, ids)


def dot(a, b):
    """Row-wise dot products summed x + y + z in this order (as the caster does; no fused multiply-add)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def brute_force(origin, dirs, tri, max_range_m):
    """Nearest hit per ray over every packed triangle (G, 9): range [m] and sorted triangle index (-1 none)."""
    a, e1, e2 = (tri[:, k:k + 3].astype(np.float64) for k in (0, 3, 6))
    s = origin[None, :] - a                                    # (G, 3)
    q = np.cross(s, e1)
    best = np.full(len(dirs), np.inf)
    index = np.full(len(dirs), -1)
    for r, d in enumerate(dirs):
        p = np.cross(np.broadcast_to(d, e2.shape), e2)
        det = dot(e1, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            u = dot(s, p) * inv
            v = (d[0] * q[:, 0] + d[1] * q[:, 1] + d[2] * q[:, 2]) * inv
            t = dot(e2, q) * inv
        ok = (np.abs(det) >= 1e-14) & (u >= 0.0) & (u <= 1.0) & (v >= 0.0) & (u + v <= 1.0) & (t >= 0.0)
        ok &= t <= max_range_m
        if ok.any():
            k = np.flatnonzero(ok)[np.argmin(t[ok])]
            best[r], index[r] = t[k], k
    return best, index


def rays(rng, n, origin_box, elevation_deg, azimuth_deg=(-180.0, 180.0)):
    """n origins uniform in origin_box ((3,) lo, (3,) hi) and unit directions with azimuths and elevations
    uniform in the given spans [deg]."""
    lo, hi = origin_box
    origins = rng.uniform(lo, hi, size=(n, 3))
    az = np.radians(rng.uniform(*azimuth_deg, n))
    el = np.radians(rng.uniform(*elevation_deg, n))
    dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    return origins, dirs


def cast_one(bvh, origin, direction, max_range_m):
    out_r, out_h = np.empty(1), np.empty(1, np.int32)
    cast_rays(np.asarray(origin, float), np.eye(3), direction[None, :].copy(), max_range_m, bvh.tri, bvh.tri_id,
              bvh.node_box, bvh.node_first, bvh.node_count, bvh.node_near, out_r, out_h)
    return out_r[0], out_h[0]


def test_tree_holds_every_triangle_once_inside_its_boxes(farm_bvh):
    _, tris, ids, bvh = farm_bvh
    assert sorted(bvh.tri_id.tolist()) == sorted(ids.tolist())
    leaf = np.flatnonzero(bvh.node_count > 0)
    covered = np.zeros(len(bvh.tri), int)
    a = bvh.tri[:, 0:3].astype(np.float64)
    corners = np.stack([a, a + bvh.tri[:, 3:6], a + bvh.tri[:, 6:9]], axis=1)
    for c in leaf:
        first, count = bvh.node_first[c], bvh.node_count[c]
        covered[first:first + count] += 1
        pts = corners[first:first + count].reshape(-1, 3)
        assert np.all(pts >= bvh.node_box[c, :3]) and np.all(pts <= bvh.node_box[c, 3:]), f"leaf {c}"
        assert count <= 8
    assert np.all(covered == 1)
    for c in np.flatnonzero(bvh.node_count == 0):
        for child in (bvh.node_first[c], bvh.node_first[c] + 1):
            assert np.all(bvh.node_box[child, :3] >= bvh.node_box[c, :3])
            assert np.all(bvh.node_box[child, 3:] <= bvh.node_box[c, 3:])
    # boxes are tight up to the padding (a box grown without need would still pass the checks above)
    root_lo = corners.reshape(-1, 3).min(axis=0)
    assert np.all(np.abs(bvh.node_box[0, :3] - (root_lo - BOX_PAD_M)) < 1e-5)
    assert 2 * len(leaf) - 1 == bvh.node_total
    assert bvh.depth < 60


@pytest.mark.parametrize("place", ["lane", "headland", "anywhere"])
def test_bvh_hits_match_brute_force(farm_bvh, place):
    farm, _, _, bvh = farm_bvh
    rng = np.random.default_rng({"lane": 1, "headland": 2, "anywhere": 3}[place])
    lane = farm.lanes[1]
    if place == "lane":          # sensor height in a lane, the VLP-16's elevations (and a little more)
        box = ([lane.x_m - 0.3, lane.y_start_m + 0.5, 0.3], [lane.x_m + 0.3, lane.y_end_m - 0.5, 0.6])
        origins, dirs = rays(rng, 300, box, (-17.0, 17.0))
    elif place == "headland":
        box = ([lane.x_m - 3.0, lane.y_start_m - 3.0, 0.3], [lane.x_m + 3.0, lane.y_start_m - 1.0, 0.6])
        origins, dirs = rays(rng, 300, box, (-17.0, 17.0), (30.0, 150.0))       # towards the rows (+y)
    else:
        lo = bvh.node_box[0, :3] - 0.5
        lo[2] = 0.05                                               # above the ground
        hi = bvh.node_box[0, 3:] + 0.5
        origins, dirs = rays(rng, 300, (lo, hi), (-89.0, 89.0))
    hits_on_plants = 0
    for o, d in zip(origins, dirs):
        max_range_m = 130.0
        got_r, got_h = cast_one(bvh, o, d, max_range_m)
        ref_r, ref_k = brute_force(o, d[None, :], bvh.tri, max_range_m)
        ground = -o[2] / d[2] if d[2] < 0.0 else math.inf
        ground = ground if ground <= max_range_m else math.inf
        if math.isfinite(ground) and ground <= ref_r[0]:       # (the ground wins a tie)
            assert got_h == HIT_GROUND and got_r == ground, (o, d, got_r, got_h, ref_r)
            continue
        if ref_k[0] < 0:
            assert got_h == HIT_NONE and got_r == math.inf, (o, d, got_r, got_h)
            continue
        hits_on_plants += 1
        assert got_r == ref_r[0], (o, d, got_r, ref_r[0])
        if got_h != bvh.tri_id[ref_k[0]]:       # a tie: the reported triangle must be at the same distance
            k = int(np.flatnonzero(bvh.tri_id == got_h)[0])
            t_k, _ = brute_force(o, d[None, :], bvh.tri[k:k + 1], max_range_m)
            assert t_k[0] == got_r
    assert hits_on_plants >= 20, f"only {hits_on_plants} rays hit a plant: the test would prove little"


def test_rays_stop_at_max_range_and_miss_an_empty_tree():
    tri = np.array([[[5.0, -1.0, -1.0], [5.0, 1.0, -1.0], [5.0, 0.0, 2.0]]])
    bvh = TriangleBVH(tri, np.array([7], np.int32))
    r, h = cast_one(bvh, [0.0, 0.0, 0.5], np.array([1.0, 0.0, 0.0]), 10.0)
    assert h == 7 and r == pytest.approx(5.0)
    r, h = cast_one(bvh, [0.0, 0.0, 0.5], np.array([1.0, 0.0, 0.0]), 4.9)
    assert h == HIT_NONE and r == math.inf
    empty = TriangleBVH(np.zeros((0, 3, 3)), np.zeros(0, np.int32))
    r, h = cast_one(empty, [0.0, 0.0, 0.5], np.array([0.6, 0.0, -0.8]), 10.0)
    assert h == HIT_GROUND and r == pytest.approx(0.625)
