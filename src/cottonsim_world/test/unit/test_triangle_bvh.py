"""The LiDAR's BVH finds exactly the nearest triangle a brute-force search finds.

The ray caster is exact only if the tree never loses a triangle a ray hits
(a box that does not contain its triangles, a subtree skipped too early).
Its hits on random rays through a small generated farm (from inside a lane,
from the headland and from anywhere above the ground) are compared with a
brute-force test of every triangle, done in numpy with the same float32
corners, origin and directions and the same float32 formulas (operation by
operation, no fused multiply-add), so the ranges must agree to the bit;
two triangles at exactly the same distance (a shared edge) may trade places.
The tree's structure is checked too: every triangle in exactly one leaf,
every box around what it holds, and the 4-wide tree the caster walks holds
the binary tree's leaves with their boxes, each once, with a visiting order
per octant that is a permutation of its slots. Whole packets (fans of
neighbouring rays of one ring, as the VLP-16 casts them) are compared with
brute force too, since a child entered for one ray of a packet must not be
lost for another.
"""
import math

import numpy as np
import pytest

from cottonsim_world.farm.generator import FarmConfig, generate_farm
from cottonsim_world.sensors.fast.bvh import (BOX_PAD_M, FAR_M, LEAF_COUNT_BITS, RECORD_CHILD, RECORD_ORDER, WIDTH,
                                             TriangleBVH, pack_records)
from cottonsim_world.sensors.fast.raycast import HIT_GROUND, HIT_NONE, PACKET, cast_rays
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
    """Nearest hit per ray over every packed triangle (G, 9): range [m] and sorted triangle index (-1 none).

    In float32 like the caster: origin and unit directions rounded to float32, then the caster's formulas.
    """
    a, e1, e2 = (np.ascontiguousarray(tri[:, k:k + 3], dtype=np.float32) for k in (0, 3, 6))
    s = np.asarray(origin, np.float64).astype(np.float32)[None, :] - a      # (G, 3)
    q = np.cross(s, e1)
    t_num = dot(e2, q)
    one, zero = np.float32(1.0), np.float32(0.0)
    best = np.full(len(dirs), np.inf)
    index = np.full(len(dirs), -1)
    for r, d in enumerate(np.asarray(dirs, np.float64).astype(np.float32)):
        p = np.cross(np.broadcast_to(d, e2.shape), e2)
        det = dot(e1, p)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            inv = one / det
            u = dot(s, p) * inv
            v = (d[0] * q[:, 0] + d[1] * q[:, 1] + d[2] * q[:, 2]) * inv
            t = t_num * inv
            ok = (np.abs(det) >= np.float32(1e-14)) & (u >= zero) & (u <= one) & (v >= zero) & (u + v <= one)
            ok &= (t >= zero) & (t.astype(np.float64) <= max_range_m)
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


def cast(bvh, origin, directions, max_range_m):
    """Ranges [m] and hits of rays from one origin along directions (N, 3), cast in packets."""
    out_r, out_h = np.empty(len(directions)), np.empty(len(directions), np.int32)
    none_hidden = np.zeros(len(bvh.tri_id), np.uint8)
    cast_rays(np.asarray(origin, float), np.eye(3), np.ascontiguousarray(directions, dtype=float), max_range_m,
              bvh.tri, bvh.tri_id, none_hidden, bvh.root_box, bvh.anchor, bvh.wide_record_f, bvh.wide_record,
              out_r, out_h)
    return out_r, out_h


def cast_one(bvh, origin, direction, max_range_m):
    out_r, out_h = cast(bvh, origin, direction[None, :], max_range_m)
    return out_r[0], out_h[0]


def check_against_brute_force(bvh, o, d, got_r, got_h, max_range_m):
    """Asserts one ray's cast result against brute force; returns True when it hit a plant."""
    ref_r, ref_k = brute_force(o, d[None, :], bvh.tri, max_range_m)
    ground = -o[2] / d[2] if d[2] < 0.0 else math.inf
    ground = float(np.float32(ground)) if ground <= max_range_m else math.inf    # (the caster keeps it in float32)
    if math.isfinite(ground) and ground <= ref_r[0]:       # (the ground wins a tie)
        assert got_h == HIT_GROUND and got_r == ground, (o, d, got_r, got_h, ref_r)
        return False
    if ref_k[0] < 0:
        assert got_h == HIT_NONE and got_r == math.inf, (o, d, got_r, got_h)
        return False
    assert got_r == ref_r[0], (o, d, got_r, ref_r[0])
    if got_h != bvh.tri_id[ref_k[0]]:       # a tie: the reported triangle must be at the same distance
        k = int(np.flatnonzero(bvh.tri_id == got_h)[0])
        t_k, _ = brute_force(o, d[None, :], bvh.tri[k:k + 1], max_range_m)
        assert t_k[0] == got_r
    return True


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
        hits_on_plants += check_against_brute_force(bvh, o, d, got_r, got_h, max_range_m)
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


def test_wide_tree_holds_the_binary_leaves_once_with_their_boxes(farm_bvh):
    _, _, _, bvh = farm_bvh
    leaves = np.flatnonzero(bvh.node_count > 0)
    binary = {(int(bvh.node_first[c]), int(bvh.node_count[c])): bvh.node_box[c].astype(np.float64) for c in leaves}
    seen, inner_seen = [], np.zeros(bvh.wide_total, int)
    inner_seen[0] = 1
    for w in range(bvh.wide_total):
        for slot in range(WIDTH):
            box = bvh.wide_box[w, slot::WIDTH]                       # min x, y, z, max x, y, z of this child
            child = int(bvh.wide_child[w, slot])
            if child >= 0:
                inner_seen[child] += 1
                # an inner child's box holds every box of its own children
                assert np.all(bvh.wide_box[child, :12].reshape(3, WIDTH).min(axis=1) >= box[:3])
                used = bvh.wide_box[child, 12:].reshape(3, WIDTH)
                used = used[:, bvh.wide_box[child, 0:WIDTH] < FAR_M]
                assert np.all(used.max(axis=1) <= box[3:])
            elif bvh.leaf_count[-1 - child] > 0:
                key = (int(bvh.leaf_first[-1 - child]), int(bvh.leaf_count[-1 - child]))
                assert np.array_equal(binary[key], box), f"wide node {w} slot {slot}"
                seen.append(key)
            else:
                assert np.all(box == FAR_M)                          # an unused slot is never met
        for octant in range(8):
            code = int(bvh.wide_order[w, octant])
            assert sorted((code >> (2 * j)) & 3 for j in range(WIDTH)) == list(range(WIDTH))
    assert sorted(seen) == sorted(binary), "every binary leaf exactly once"
    assert np.all(inner_seen == 1), "every wide node reached exactly once"
    assert bvh.wide_total < bvh.node_total / 3


def test_records_hold_the_wide_tree_the_caster_walks(farm_bvh):
    """Each 128-byte record decodes to its node's boxes, child references (leaves with their triangle
    range) and the 8 visiting orders; a leaf too large for the packing is refused."""
    _, _, _, bvh = farm_bvh
    rec = bvh.wide_record
    assert rec.shape == (bvh.wide_total, 32) and rec.ctypes.data % 64 == 0
    boxes = bvh.wide_record_f[:, :RECORD_CHILD].reshape(-1, 6, WIDTH).astype(np.float64)
    world = bvh.wide_box.reshape(-1, 6, WIDTH).astype(np.float64)
    used = world[:, 0:1, :] < FAR_M
    expected = world - np.tile(bvh.anchor, 2)[None, :, None]
    assert np.all(np.abs(boxes - expected)[np.broadcast_to(used, boxes.shape)] <= 1e-6), "boxes relative to the anchor"
    assert np.all(boxes[np.broadcast_to(~used, boxes.shape)] == np.float32(FAR_M)), "unused slots stay far away"
    for slot in range(WIDTH):
        ref = rec[:, RECORD_CHILD + slot].astype(np.int64)
        child = bvh.wide_child[:, slot].astype(np.int64)
        inner = child >= 0
        assert np.array_equal(ref[inner], child[inner])
        leaf = -1 - child[~inner]
        packed = -1 - ref[~inner]
        assert np.array_equal(packed >> LEAF_COUNT_BITS, bvh.leaf_first[leaf])
        assert np.array_equal(packed & ((1 << LEAF_COUNT_BITS) - 1), bvh.leaf_count[leaf])
    for octant in range(8):
        word = rec[:, RECORD_ORDER + octant // 4].view(np.uint32).astype(np.int64)
        assert np.array_equal((word >> (8 * (octant % 4))) & 0xFF, bvh.wide_order[:, octant])
    too_big = bvh.leaf_count.copy()
    too_big[0] = 1 << LEAF_COUNT_BITS
    with pytest.raises(ValueError, match="leaf holds 16 triangles"):
        pack_records(bvh.wide_box, bvh.wide_child, bvh.wide_order, bvh.leaf_first, too_big, bvh.anchor)


def test_far_origins_match_brute_force(farm_bvh):
    """The slab tests run in float32: from 60-120 m away (long t, large coordinates) no triangle is lost."""
    farm, _, _, bvh = farm_bvh
    rng = np.random.default_rng(11)
    centre = 0.5 * (bvh.node_box[0, :3].astype(np.float64) + bvh.node_box[0, 3:])
    hits_on_plants = 0
    for _ in range(200):
        distance = rng.uniform(60.0, 120.0)
        bearing = rng.uniform(-math.pi, math.pi)
        origin = centre + np.array([distance * math.cos(bearing), distance * math.sin(bearing), 0.0])
        origin[2] = rng.uniform(0.3, 2.0)
        target = centre + rng.uniform([-3.0, -3.0, 0.2], [3.0, 3.0, 0.9])   # somewhere in the plants
        d = (target - origin) / np.linalg.norm(target - origin)
        got_r, got_h = cast_one(bvh, origin, d, 130.0)
        hits_on_plants += check_against_brute_force(bvh, origin, d, got_r, got_h, 130.0)
    assert hits_on_plants >= 20, f"only {hits_on_plants} rays hit a plant: the test would prove little"


@pytest.mark.parametrize("place", ["lane", "headland"])
def test_packets_of_a_ring_match_brute_force(farm_bvh, place):
    """Fans of 3 packets of neighbouring rays (0.4 deg apart, one elevation) per origin, cast together."""
    farm, _, _, bvh = farm_bvh
    rng = np.random.default_rng({"lane": 4, "headland": 5}[place])
    lane = farm.lanes[1]
    if place == "lane":
        box = ([lane.x_m - 0.3, lane.y_start_m + 0.5, 0.3], [lane.x_m + 0.3, lane.y_end_m - 0.5, 0.6])
        az_span = (-180.0, 180.0)
    else:
        box = ([lane.x_m - 3.0, lane.y_start_m - 3.0, 0.3], [lane.x_m + 3.0, lane.y_start_m - 1.0, 0.6])
        az_span = (30.0, 150.0)
    hits_on_plants = 0
    n_rays = 3 * PACKET
    for origin, start in zip(*rays(rng, 12, box, (-15.0, 15.0), az_span)):
        el = math.asin(start[2])
        az = math.atan2(start[1], start[0]) + np.radians(0.4) * np.arange(n_rays)
        dirs = np.stack([math.cos(el) * np.cos(az), math.cos(el) * np.sin(az), np.full(n_rays, math.sin(el))], axis=1)
        got_r, got_h = cast(bvh, origin, dirs, 130.0)
        for d, r, h in zip(dirs, got_r, got_h):
            hits_on_plants += check_against_brute_force(bvh, origin, d, r, h, 130.0)
    assert hits_on_plants >= 20, f"only {hits_on_plants} rays hit a plant: the test would prove little"
