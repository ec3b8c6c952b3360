"""Numba ray caster for the VLP-16: nearest hit against the farm's triangles.

Why: pybullet's rayTestBatch needs 140-500 ms per 14,400-ray scan of the
default farm (and 4-6 s to build its collision world). Here the rays descend
the 4-wide tree of ``bvh.TriangleBVH`` in *packets* of ``PACKET`` rays: all
rays of a scan share the sensor's origin, and rays next to each other in a
ring (0.4 deg apart) cross nearly the same boxes, so at each node the packet
tests the 4 children's boxes against all its rays in one loop that LLVM
vectorises over the rays: per axis t = corner / d - origin / d, one fused
multiply-subtract per ray, corner and axis (``_meets`` alone is compiled
with fast-math contraction). Everything per ray runs in float32, in loops
that LLVM vectorises, so one AVX2 vector holds a packet's 8 rays:

* slab tests: exactly ``PACKET`` iterations (a short last packet fills its
  spare lanes with rays that meet nothing); each child's "some ray meets
  it" is one boolean any-reduction. They only prune, so they only need to
  be conservative: the records hold the boxes relative to the tree's
  anchor (coordinates of a few metres wherever the farm lies), padded by
  ``bvh.BOX_PAD_M`` (0.1 mm), and the limit is rounded up by
  ``_LIMIT_SLACK``; float32 rounding of the products (~1e-7 of coordinates
  and distances of tens of metres) stays well inside that margin, so the
  boxes entered are never fewer than float64 slab tests enter
  (``test_triangle_bvh`` casts from 60-120 m too);
* triangle tests (Moeller-Trumbore, both faces count; the cross products
  with the shared corner are done once per triangle, the vector computes
  per ray exactly what a lone ray's test computes). In float32 a range
  carries ~1e-7 of itself in rounding (1 um at 10 m, far below the 8 mm
  range noise and the float32 points published), and a ray within about
  that of a triangle's edge may hit the neighbouring triangle instead.
  Against a float64 triangle test: 2 of 115,200 rays of
  ``bench_lidar``'s 8 poses hit another triangle, ranges within 5 mm
  (those two) and 2e-4 m (the rest); the lane cast costs 12 % less.

The tree is read from one 128-byte record per wide node
(``bvh.pack_records``). A child is entered when at least one ray meets it
before that ray's nearest hit so far (the ground's included), in the order
the binary tree would visit them for the octant the packet looks to
(``bvh._collapse``), so hits and ties are those of a binary walk. The
ground is the analytic plane z = 0 (infinite, like pybullet's
GEOM_PLANE). Packets are independent and run in parallel (``prange``),
interleaved so that both threads get rays of every ring (the low rings end
on the ground early, the high ones cross the hedges).

Result per ray: the hit distance [m] along the unit direction and what was
hit: a global triangle id (>= 0), ``HIT_GROUND`` or ``HIT_NONE``.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from cottonsim_world.sensors.fast.bvh import LEAF_COUNT_BITS, RECORD_CHILD, RECORD_ORDER

HIT_NONE = -1
HIT_GROUND = -2
PACKET = 8                 # rays traversing the tree together (consecutive rays: neighbours in a ring)
_WORK_ITEMS = 16           # parallel items; item i casts packets i, i + 16, i + 32, ...
_STACK = 256               # pending entries: at most 3 per wide level (+ 1), and 3 * bvh.MAX_DEPTH + 1 < _STACK
_LEAF_COUNT_MASK = (1 << LEAF_COUNT_BITS) - 1
_SLOT_OF_BIT = np.array([0, 0, 1, 0, 2, 0, 0, 0, 3], np.int64)   # child slot of a one-bit mask
_MAX_RECIPROCAL = 1e30    # cap on |1 / direction component| in the float32 slab test (finite: no 0 * inf)
_LIMIT_SLACK = 1e-6        # the slab test's limit: min(best, max_range) * (1 + this) + _LIMIT_SLACK_M
_LIMIT_SLACK_M = 1e-4      # [m]; with BOX_PAD_M it covers float32 rounding (see the module doc)
_MIN_DET = 1e-14           # |determinant| below this: the ray runs parallel to the triangle


@njit(cache=True, inline="always")
def _child_box(record_f, w, slot):  # pragma: no cover
    """Child ``slot`` of wide node w: its min and max corners (x0, y0, z0, x1, y1, z1) [m] relative to the
    records' anchor, float32."""
    return (record_f[w, slot], record_f[w, 4 + slot], record_f[w, 8 + slot],
            record_f[w, 12 + slot], record_f[w, 16 + slot], record_f[w, 20 + slot])


@njit(cache=True, fastmath={"contract"})
def _meets(b0x, b0y, b0z, b1x, b1y, b1z, ix, iy, iz, oix, oiy, oiz, limit, zero):  # pragma: no cover
    """Whether the ray from o with reciprocal direction (ix, iy, iz) meets the box within [0, limit] [m].

    oix = o_x * ix etc.; box corners and o relative to the tree's anchor.
    Slab test in float32: every argument and ``zero`` are float32, so the
    packet's 8 rays fill one AVX2 vector; t = corner * i - o * i is one
    fused multiply-subtract; min / max are spelled as selects, which
    vectorise. Not inlined by numba, so that its fast-math contraction
    stays with it: LLVM inlines it into the caller's vectorised loop.
    """
    t0x, t1x = b0x * ix - oix, b1x * ix - oix
    t0y, t1y = b0y * iy - oiy, b1y * iy - oiy
    t0z, t1z = b0z * iz - oiz, b1z * iz - oiz
    nx = t0x if t0x < t1x else t1x
    fx = t0x if t0x > t1x else t1x
    ny = t0y if t0y < t1y else t1y
    fy = t0y if t0y > t1y else t1y
    nz = t0z if t0z < t1z else t1z
    fz = t0z if t0z > t1z else t1z
    near = nx if nx > ny else ny
    near = near if near > nz else nz
    near = near if near > zero else zero
    far = fx if fx < fy else fy
    far = far if far < fz else fz
    far = far if far < limit else limit
    return near <= far


@njit(cache=True, inline="always")
def _reciprocal32(d):  # pragma: no cover
    """1 / d as float32, its magnitude capped at _MAX_RECIPROCAL (a zero component: +-inf capped, finite;
    selects, no branches, so that the packet's set-up loop vectorises)."""
    r = 1.0 / d
    r = r if r < _MAX_RECIPROCAL else _MAX_RECIPROCAL
    r = r if r > -_MAX_RECIPROCAL else -_MAX_RECIPROCAL
    return np.float32(r)


@njit(cache=True, inline="always")
def _box_limit32(t):  # pragma: no cover
    """A float32 limit for the slab test at or beyond t [m] (rounding never prunes a box that holds a
    hit nearer than t)."""
    return np.float32(t * (1.0 + _LIMIT_SLACK) + _LIMIT_SLACK_M)


@njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def cast_rays(origin, rot, dirs, max_range, tri, tri_id, tri_hidden, root_box, anchor, record_f, record_i,
              out_range, out_hit):  # pragma: no cover
    """Cast rays from ``origin`` along ``rot @ dirs[i]`` (unit) up to max_range [m].

    tri (G, 9) float32: corner, edge, edge per sorted triangle; tri_id maps
    the sorted index to the global id; tri_hidden (G,) uint8 per sorted
    triangle: 1 = rays pass through it (a hidden boll's,
    ``SensorScene.visibility.triangle_hidden``); root_box (6,) [m]; anchor (3,) [m]:
    the point the records' boxes are relative to; record_f / record_i:
    float32 and int32 views of ``bvh.TriangleBVH.wide_record`` (the 4-wide
    tree, one 128-byte record per node, see ``bvh.pack_records``).

    Writes out_range (N,) [m] (inf when nothing is hit) and out_hit (N,)
    int32: triangle id, HIT_GROUND or HIT_NONE.
    """
    n = dirs.shape[0]
    ox, oy, oz = origin[0], origin[1], origin[2]
    ox32, oy32, oz32 = np.float32(ox), np.float32(oy), np.float32(oz)
    # the origin relative to the records' anchor, for the slab tests (small numbers wherever the farm is)
    ax32, ay32, az32 = np.float32(ox - anchor[0]), np.float32(oy - anchor[1]), np.float32(oz - anchor[2])
    zero32, one32, min_det32 = np.float32(0.0), np.float32(1.0), np.float32(_MIN_DET)
    n_packets = (n + PACKET - 1) // PACKET
    has_tree = tri.shape[0] > 0
    for item in prange(_WORK_ITEMS):
        stack = np.empty(_STACK, np.int32)   # pending children: references as in the record (>= 0 a wide node)
        dxa = np.empty(PACKET, np.float32)   # unit directions in the world frame
        dya = np.empty(PACKET, np.float32)
        dza = np.empty(PACKET, np.float32)
        ixa = np.empty(PACKET, np.float32)   # reciprocal directions for the float32 slab tests
        iya = np.empty(PACKET, np.float32)
        iza = np.empty(PACKET, np.float32)
        oixa = np.empty(PACKET, np.float32)  # origin times reciprocal direction: t = corner * i - o * i
        oiya = np.empty(PACKET, np.float32)
        oiza = np.empty(PACKET, np.float32)
        best = np.empty(PACKET, np.float32)  # nearest hit so far per ray [m]
        limit = np.empty(PACKET, np.float32)  # >= min(best, max_range) [m]: boxes beyond are skipped
        hit = np.empty(PACKET, np.int32)
        for packet in range(item, n_packets, _WORK_ITEMS):
            r0 = packet * PACKET
            m = min(PACKET, n - r0)
            for k in range(m):
                sx, sy, sz = dirs[r0 + k, 0], dirs[r0 + k, 1], dirs[r0 + k, 2]
                dx = rot[0, 0] * sx + rot[0, 1] * sy + rot[0, 2] * sz
                dy = rot[1, 0] * sx + rot[1, 1] * sy + rot[1, 2] * sz
                dz = rot[2, 0] * sx + rot[2, 1] * sy + rot[2, 2] * sz
                dxa[k], dya[k], dza[k] = np.float32(dx), np.float32(dy), np.float32(dz)
                ixa[k], iya[k], iza[k] = _reciprocal32(dx), _reciprocal32(dy), _reciprocal32(dz)
                oixa[k], oiya[k], oiza[k] = ax32 * ixa[k], ay32 * iya[k], az32 * iza[k]
                tg = -oz / dz
                on_ground = (dz < 0.0) & (oz > 0.0) & (tg <= max_range)
                t_first = tg if on_ground else math.inf
                best[k] = np.float32(t_first)
                hit[k] = HIT_GROUND if on_ground else HIT_NONE
                limit[k] = _box_limit32(t_first if t_first < max_range else max_range)
            for k in range(m, PACKET):    # the lanes of a short last packet meet no box
                ixa[k], iya[k], iza[k], limit[k] = one32, one32, one32, -one32
                oixa[k], oiya[k], oiza[k] = zero32, zero32, zero32
            # the octant the packet's middle ray looks to picks each node's visiting order
            h = m // 2
            octant = (1 if dxa[h] >= zero32 else 0) | (2 if dya[h] >= zero32 else 0) | (4 if dza[h] >= zero32 else 0)
            order_word, order_shift = RECORD_ORDER + (octant >> 2), 8 * (octant & 3)
            sp = 0
            if has_tree:     # the root's own box first: a packet that misses the farm costs one box test
                b0x, b1x = np.float32(root_box[0] - anchor[0]), np.float32(root_box[3] - anchor[0])
                b0y, b1y = np.float32(root_box[1] - anchor[1]), np.float32(root_box[4] - anchor[1])
                b0z, b1z = np.float32(root_box[2] - anchor[2]), np.float32(root_box[5] - anchor[2])
                meeting = False
                for k in range(PACKET):
                    meeting |= _meets(b0x, b0y, b0z, b1x, b1y, b1z, ixa[k], iya[k], iza[k], oixa[k], oiya[k], oiza[k],
                                      limit[k], zero32)
                if meeting:
                    stack[0] = 0
                    sp = 1
            while sp > 0:
                # invariant: some ray of the packet met this entry's box (when it was tested)
                sp -= 1
                node = stack[sp]
                if node >= 0:
                    # the 4 children's boxes against every ray of the packet, in one vectorised loop;
                    # bit s of met: some ray meets child s
                    a0x, a0y, a0z, a1x, a1y, a1z = _child_box(record_f, node, 0)
                    b0x, b0y, b0z, b1x, b1y, b1z = _child_box(record_f, node, 1)
                    c0x, c0y, c0z, c1x, c1y, c1z = _child_box(record_f, node, 2)
                    d0x, d0y, d0z, d1x, d1y, d1z = _child_box(record_f, node, 3)
                    met_a = met_b = met_c = met_d = False
                    for k in range(PACKET):
                        ix, iy, iz, lim = ixa[k], iya[k], iza[k], limit[k]
                        oix, oiy, oiz = oixa[k], oiya[k], oiza[k]
                        met_a |= _meets(a0x, a0y, a0z, a1x, a1y, a1z, ix, iy, iz, oix, oiy, oiz, lim, zero32)
                        met_b |= _meets(b0x, b0y, b0z, b1x, b1y, b1z, ix, iy, iz, oix, oiy, oiz, lim, zero32)
                        met_c |= _meets(c0x, c0y, c0z, c1x, c1y, c1z, ix, iy, iz, oix, oiy, oiz, lim, zero32)
                        met_d |= _meets(d0x, d0y, d0z, d1x, d1y, d1z, ix, iy, iz, oix, oiy, oiz, lim, zero32)
                    met = (1 if met_a else 0) | (2 if met_b else 0) | (4 if met_c else 0) | (8 if met_d else 0)
                    if met & (met - 1) == 0:          # none or one child met: no order to look up
                        if met != 0:
                            stack[sp] = record_i[node, RECORD_CHILD + _SLOT_OF_BIT[met]]
                            sp += 1
                    else:
                        order = (record_i[node, order_word] >> order_shift) & 0xFF
                        for j in range(3, -1, -1):    # the last to visit is pushed first
                            slot = (order >> (2 * j)) & 3
                            if (met >> slot) & 1:
                                stack[sp] = record_i[node, RECORD_CHILD + slot]
                                sp += 1
                else:
                    leaf = -1 - node
                    first = leaf >> LEAF_COUNT_BITS
                    for g in range(first, first + (leaf & _LEAF_COUNT_MASK)):
                        if tri_hidden[g] != 0:
                            continue
                        ax, ay, az = tri[g, 0], tri[g, 1], tri[g, 2]
                        e1x, e1y, e1z = tri[g, 3], tri[g, 4], tri[g, 5]
                        e2x, e2y, e2z = tri[g, 6], tri[g, 7], tri[g, 8]
                        sx, sy, sz = ox32 - ax, oy32 - ay, oz32 - az
                        qx = sy * e1z - sz * e1y
                        qy = sz * e1x - sx * e1z
                        qz = sx * e1y - sy * e1x
                        t_num = e2x * qx + e2y * qy + e2z * qz
                        gid = tri_id[g]
                        for k in range(m):
                            dx, dy, dz = dxa[k], dya[k], dza[k]
                            px = dy * e2z - dz * e2y
                            py = dz * e2x - dx * e2z
                            pz = dx * e2y - dy * e2x
                            det = e1x * px + e1y * py + e1z * pz
                            inv = one32 / det
                            u = (sx * px + sy * py + sz * pz) * inv
                            v = (dx * qx + dy * qy + dz * qz) * inv
                            t = t_num * inv
                            nearer = (abs(det) >= min_det32) & (u >= zero32) & (u <= one32) & (v >= zero32) \
                                & (u + v <= one32) & (t >= zero32) & (t < best[k])
                            best[k] = t if nearer else best[k]
                            hit[k] = gid if nearer else hit[k]
                    for k in range(m):
                        nearest_m = np.float64(best[k])
                        limit[k] = _box_limit32(nearest_m if nearest_m < max_range else max_range)
                # pending entries are not tested again: nearer hits since they were pushed may make them moot
            for k in range(m):
                far_hit = np.float64(best[k]) > max_range
                out_range[r0 + k] = math.inf if far_hit else best[k]
                out_hit[r0 + k] = HIT_NONE if far_hit else hit[k]


@njit(cache=True, nogil=True)
def gather_returns(ranges, hits, noise, min_m, max_m, dirs, ring, azimuth, g_semantic, g_plant, ground_class,
                   sky_class, reflectivity):  # pragma: no cover
    """The returns of a cast, packed: what ``lidar.Vlp16Model.scan`` publishes.

    ranges (N,) [m] (inf = no hit) and hits (N,) from ``cast_rays``; noise
    (N,) [m] added to the hit rays' ranges (or an empty array: none); a ray
    is kept when it hit something and its noisy range lies in [min_m,
    max_m]. dirs (N, 3) unit ray directions in the sensor frame. Returns,
    in ray order: points (K, 3) float32 = dirs * range [m], ring (K,),
    intensity (K,) float32 = reflectivity[semantic], azimuth (K,),
    semantic (K,) uint8, plant id (K,) int32 (-1 off the plants).
    """
    n = ranges.shape[0]
    with_noise = noise.shape[0] == n
    keep = np.zeros(n, np.bool_)
    count = 0
    for i in range(n):
        r = ranges[i]
        if math.isfinite(r):
            if with_noise:
                r += noise[i]
            if min_m <= r <= max_m:
                keep[i] = True
                count += 1
    points = np.empty((count, 3), np.float32)
    out_ring = np.empty(count, ring.dtype)
    intensity = np.empty(count, np.float32)
    out_az = np.empty(count, azimuth.dtype)
    semantic = np.empty(count, np.uint8)
    plant = np.empty(count, np.int32)
    k = 0
    for i in range(n):
        if not keep[i]:
            continue
        r = ranges[i] + noise[i] if with_noise else ranges[i]
        points[k, 0] = np.float32(dirs[i, 0] * r)
        points[k, 1] = np.float32(dirs[i, 1] * r)
        points[k, 2] = np.float32(dirs[i, 2] * r)
        h = hits[i]
        if h >= 0:
            s = g_semantic[h]
            plant[k] = g_plant[h]
        else:
            s = ground_class if h == HIT_GROUND else sky_class
            plant[k] = -1
        semantic[k] = s
        intensity[k] = reflectivity[s]
        out_ring[k] = ring[i]
        out_az[k] = azimuth[i]
        k += 1
    return points, out_ring, intensity, out_az, semantic, plant
