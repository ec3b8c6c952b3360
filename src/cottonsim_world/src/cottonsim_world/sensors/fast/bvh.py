"""Bounding volume hierarchy over the farm's world-space triangles, for the numba LiDAR.

Why: a uniform grid makes a ray inside a crop lane step through ~25 small
cells of the hedges before it hits a leaf (or grazes along the row); a BVH
adapts to where the leaves are, so the empty lane, the sky and the space
between the rows cost a few box tests.

Layout (built once per scene, ``TriangleBVH``): first a binary tree, root
0, whose two children are stored next to each other (node c's children are
``node_first[c]`` and ``node_first[c] + 1``). A leaf (``node_count[c] >
0``) lists the sorted triangles ``node_first[c] .. node_first[c] +
node_count[c] - 1``. Triangles are stored in leaf order as float32 corner +
two edges, exactly what the ray/triangle test reads (float32 storage:
float64 copies of triangles and boxes saved ~5 % of the lane cast's
instructions but no CPU time, the larger arrays missing the caches more); the boxes are computed from those
corners (so they bound the triangle the test sees) and padded by
``BOX_PAD_M`` against rounding in the (float32) slab test.

The caster walks a **4-wide** tree collapsed from the binary one
(``_collapse``): each wide node holds up to 4 child boxes (grandchildren or
great-grandchildren of a binary node: the inner child with the largest
area is opened until there are 4), so a packet of rays tests 4 boxes in one
vectorised loop per visit and visits about half as many nodes. Per wide
node and per octant of a packet's looking direction, ``wide_order`` holds
the order in which the binary tree would have visited those children, so
the hits (and the triangle reported when two lie at the same distance) are
those of the binary walk. The caster reads each wide node as one 128-byte
record (``pack_records``): boxes, child references with the leaves'
triangle ranges, and the visiting orders.

Build: top-down binned surface-area heuristic (SAH): per node the triangle
centroids are binned into ``_BINS`` bins along each axis, the split with
the least expected cost (children's box areas times triangle counts) wins,
unless keeping a leaf is cheaper. The "area" is weighted for the VLP-16's
rays (``_TOP_FACE_WEIGHT``, see ``_box_area``). O(N log N); ~1.3 s CPU for
the default farm's 380 k triangles.
"""
from __future__ import annotations

import numpy as np
from numba import njit

BOX_PAD_M = 1e-4          # boxes grown by this [m] on every side (float32 boxes and slab test; see raycast)
_BINS = 32                # SAH bins per axis
_MAX_LEAF = 8             # a node with more triangles is always split (by count if its centroids coincide)
_TRAVERSAL_COST = 1.0     # cost of one node visit, in units of a ray/triangle test (measured: 4-wide packets)
_TOP_FACE_WEIGHT = 0.2    # weight of a box's horizontal faces in its SAH area (vertical faces: 1)
WIDTH = 4                 # children per node of the caster's wide tree
FAR_M = 1e30              # an unused wide child's box is the point (FAR_M, FAR_M, FAR_M) [m]: never met
MAX_DEPTH = 60            # the tree is never deeper (the caster's stack holds one entry per level)
RECORD_WORDS = 32         # 4-byte words of one wide node's record (128 bytes: two cache lines)
RECORD_CHILD = 24         # record words: 0..23 the 4 child boxes (as wide_box), 24..27 the child references,
RECORD_ORDER = 28         # 28..29 the 8 octants' visiting orders (one byte each), 30..31 unused (0)
LEAF_COUNT_BITS = 4       # a leaf reference packs first << LEAF_COUNT_BITS | count (count < 16)


@njit(cache=True)
def _box_area(bx):  # pragma: no cover - compiled
    """Weighted half surface area of box (minx, miny, minz, maxx, maxy, maxz) [m^2]; 0 for an empty box.

    SAH takes a box's area as the chance that a random ray meets it. The
    VLP-16's rays lie within +-15 deg of horizontal (mean |sin| of the ring
    elevations ~0.13 against ~0.63 for a horizontal axis), so they meet a
    box mostly through its vertical faces: the horizontal faces count
    ``_TOP_FACE_WEIGHT`` (0.2 measured best of 0.05 / 0.1 / 0.2 / 0.5 / 1 on
    the lane casts). Only the tree's shape depends on it, not the hits.
    """
    ex, ey, ez = bx[3] - bx[0], bx[4] - bx[1], bx[5] - bx[2]
    if ex < 0.0 or ey < 0.0 or ez < 0.0:
        return 0.0
    return _TOP_FACE_WEIGHT * ex * ey + ey * ez + ez * ex


@njit(cache=True)
def _build(tri_box, centroid):  # pragma: no cover - compiled
    """Binned-SAH tree over triangle boxes (G, 6) and centroids (G, 3), float64 [m].

    Returns the triangle order (G,) int64, node boxes (N, 6) float64,
    node_first (N,) int64, node_count (N,) int64 (see the module doc) and
    the tree's depth (root = 1).
    """
    g = tri_box.shape[0]
    order = np.arange(g)
    cap = max(2 * g, 1)
    node_box = np.empty((cap, 6))
    node_first = np.zeros(cap, dtype=np.int64)
    node_count = np.zeros(cap, dtype=np.int64)
    # work stack of (node, start, end, depth)
    work = np.empty((2 * MAX_DEPTH + 8, 4), dtype=np.int64)
    work[0] = (0, 0, g, 0)
    sp = 1
    n_nodes = 1
    max_depth = 0
    bin_box = np.empty((_BINS, 6))
    bin_count = np.zeros(_BINS, dtype=np.int64)
    right_area = np.empty(_BINS)
    right_count = np.zeros(_BINS, dtype=np.int64)
    acc = np.empty(6)
    while sp > 0:
        sp -= 1
        node, start, end, depth = work[sp, 0], work[sp, 1], work[sp, 2], work[sp, 3]
        count = end - start
        max_depth = max(max_depth, depth + 1)
        bx = node_box[node]
        bx[:3] = np.inf
        bx[3:] = -np.inf
        cmin = np.full(3, np.inf)
        cmax = np.full(3, -np.inf)
        for k in range(start, end):
            i = order[k]
            for a in range(3):
                bx[a] = min(bx[a], tri_box[i, a])
                bx[3 + a] = max(bx[3 + a], tri_box[i, 3 + a])
                cmin[a] = min(cmin[a], centroid[i, a])
                cmax[a] = max(cmax[a], centroid[i, a])
        node_first[node] = start
        node_count[node] = count
        if count <= 2 or depth >= MAX_DEPTH - 1:
            continue
        # best split over all axes
        best_cost = np.inf
        best_axis = -1
        best_bin = 0
        for a in range(3):
            span = cmax[a] - cmin[a]
            if not span > 0.0:
                continue
            scale = _BINS / span
            bin_count[:] = 0
            bin_box[:, :3] = np.inf
            bin_box[:, 3:] = -np.inf
            for k in range(start, end):
                i = order[k]
                b = min(int((centroid[i, a] - cmin[a]) * scale), _BINS - 1)
                bin_count[b] += 1
                for q in range(3):
                    bin_box[b, q] = min(bin_box[b, q], tri_box[i, q])
                    bin_box[b, 3 + q] = max(bin_box[b, 3 + q], tri_box[i, 3 + q])
            # sweep from the right: area and count of bins b .. BINS - 1
            acc[:3] = np.inf
            acc[3:] = -np.inf
            n_right = 0
            for b in range(_BINS - 1, 0, -1):
                for q in range(3):
                    acc[q] = min(acc[q], bin_box[b, q])
                    acc[3 + q] = max(acc[3 + q], bin_box[b, 3 + q])
                n_right += bin_count[b]
                right_area[b] = _box_area(acc)
                right_count[b] = n_right
            acc[:3] = np.inf
            acc[3:] = -np.inf
            n_left = 0
            for b in range(0, _BINS - 1):
                for q in range(3):
                    acc[q] = min(acc[q], bin_box[b, q])
                    acc[3 + q] = max(acc[3 + q], bin_box[b, 3 + q])
                n_left += bin_count[b]
                if n_left == 0 or right_count[b + 1] == 0:
                    continue
                cost = _box_area(acc) * n_left + right_area[b + 1] * right_count[b + 1]
                if cost < best_cost:
                    best_cost = cost
                    best_axis = a
                    best_bin = b
        area = _box_area(bx)
        leaf_cost = area * count
        split_cost = _TRAVERSAL_COST * area + best_cost
        if count <= _MAX_LEAF and (best_axis < 0 or leaf_cost <= split_cost):
            continue
        # partition [start, end) by the chosen plane (or by count if the centroids coincide)
        if best_axis >= 0:
            a = best_axis
            scale = _BINS / (cmax[a] - cmin[a])
            lo, hi = start, end - 1
            while lo <= hi:
                i = order[lo]
                if min(int((centroid[i, a] - cmin[a]) * scale), _BINS - 1) <= best_bin:
                    lo += 1
                else:
                    order[lo], order[hi] = order[hi], order[lo]
                    hi -= 1
            mid = lo
        else:
            mid = start + count // 2
        if mid == start or mid == end:
            mid = start + count // 2
        left = n_nodes
        n_nodes += 2
        node_first[node] = left
        node_count[node] = 0
        work[sp] = (left, start, mid, depth + 1)
        work[sp + 1] = (left + 1, mid, end, depth + 1)
        sp += 2
    return order, node_box[:n_nodes].copy(), node_first[:n_nodes].copy(), node_count[:n_nodes].copy(), max_depth


@njit(cache=True)
def _collapse(node_box, node_first, node_count, node_near):  # pragma: no cover - compiled
    """The 4-wide tree of a binary tree (see the module doc).

    node_box (N, 6) float32, node_first / node_count (N,) int64, node_near
    (N,) int8 of the binary tree. Returns wide_box (W, 24) float64 (the
    float32 values; ``TriangleBVH`` stores them as float32): per
    wide node min x, min y, min z, max x, max y, max z, each for children
    0..3 (so one coordinate of the 4 children is contiguous); wide_child
    (W, 4) int32: >= 0 a wide node, < 0 leaf number -1 - child; wide_order
    (W, 8) int32: per octant of the looking direction (bit 0: x >= 0, bit
    1: y >= 0, bit 2: z >= 0) the 4 child slots in visiting order, 2 bits
    each, first in the lowest bits; leaf_first, leaf_count (L,) int32: the
    leaves' triangle ranges (an unused slot points at an empty leaf).
    """
    n = node_first.shape[0]
    wide_box = np.empty((n + 1, 6 * WIDTH))
    wide_child = np.zeros((n + 1, WIDTH), np.int32)
    wide_order = np.zeros((n + 1, 8), np.int32)
    leaf_first = np.zeros(WIDTH * (n + 1), np.int32)
    leaf_count = np.zeros(WIDTH * (n + 1), np.int32)
    n_leaves = 0
    n_wide = 1
    work = np.empty((n + 1, 2), np.int64)     # (binary node, its wide node) still to be expanded
    work[0, 0] = 0
    work[0, 1] = 0
    sp = 1
    # one wide node's part of the binary tree: entry e is binary node part_node[e]; part_kids[e] its two
    # entries once opened (-1: not opened, i.e. a child of the wide node, in slot part_slot[e])
    part_node = np.empty(2 * WIDTH, np.int64)
    part_kids = np.empty((2 * WIDTH, 2), np.int64)
    part_slot = np.empty(2 * WIDTH, np.int64)
    slot_node = np.empty(WIDTH, np.int64)
    box = np.empty(6)
    pending = np.empty(2 * WIDTH, np.int64)
    while sp > 0:
        sp -= 1
        b, w = work[sp, 0], work[sp, 1]
        part_node[0] = b
        part_kids[0, 0] = -1
        part_kids[0, 1] = -1
        n_part = 1
        n_open = 1                             # entries not opened (the wide node's children so far)
        while n_open < WIDTH:
            # open the inner entry with the largest (weighted) area: its box is the likeliest to be met
            pick = -1
            pick_area = -1.0
            for e in range(n_part):
                c = part_node[e]
                if part_kids[e, 0] < 0 and node_count[c] == 0:
                    for q in range(6):
                        box[q] = node_box[c, q]
                    area = _box_area(box)
                    if area > pick_area:
                        pick_area = area
                        pick = e
            if pick < 0:
                break
            left = node_first[part_node[pick]]
            for side in range(2):
                part_node[n_part + side] = left + side
                part_kids[n_part + side, 0] = -1
                part_kids[n_part + side, 1] = -1
            part_kids[pick, 0] = n_part
            part_kids[pick, 1] = n_part + 1
            n_part += 2
            n_open += 1
        n_slots = 0
        for e in range(n_part):
            if part_kids[e, 0] < 0:
                part_slot[e] = n_slots
                slot_node[n_slots] = part_node[e]
                n_slots += 1
        for slot in range(WIDTH):
            if slot < n_slots:
                c = slot_node[slot]
                for q in range(6):
                    wide_box[w, q * WIDTH + slot] = node_box[c, q]
                if node_count[c] > 0:
                    leaf_first[n_leaves] = node_first[c]
                    leaf_count[n_leaves] = node_count[c]
                    wide_child[w, slot] = -1 - n_leaves
                    n_leaves += 1
                else:
                    wide_child[w, slot] = n_wide
                    work[sp, 0] = c
                    work[sp, 1] = n_wide
                    sp += 1
                    n_wide += 1
            else:
                for q in range(6):
                    wide_box[w, q * WIDTH + slot] = FAR_M
                leaf_first[n_leaves] = 0
                leaf_count[n_leaves] = 0
                wide_child[w, slot] = -1 - n_leaves
                n_leaves += 1
        # visiting order per octant: the binary walk over this part (near child first), unused slots last
        for octant in range(8):
            code = 0
            position = 0
            top = 1
            pending[0] = 0
            while top > 0:
                top -= 1
                e = pending[top]
                if part_kids[e, 0] < 0:
                    code |= part_slot[e] << (2 * position)
                    position += 1
                    continue
                near = node_near[part_node[e]]
                right_low = (near & 1) == 1
                looks_up = ((octant >> (near >> 1)) & 1) == 1
                if looks_up != right_low:           # the left child is the near one: it is popped first
                    pending[top] = part_kids[e, 1]
                    pending[top + 1] = part_kids[e, 0]
                else:
                    pending[top] = part_kids[e, 0]
                    pending[top + 1] = part_kids[e, 1]
                top += 2
            for slot in range(n_slots, WIDTH):
                code |= slot << (2 * position)
                position += 1
            wide_order[w, octant] = code
    return (wide_box[:n_wide].copy(), wide_child[:n_wide].copy(), wide_order[:n_wide].copy(),
            leaf_first[:n_leaves].copy(), leaf_count[:n_leaves].copy())


class TriangleBVH:
    """World-space triangles of the farm in a binary BVH and its 4-wide form (see the module doc).

    tri (G, 9) float32: per sorted triangle its first
    corner and its two edge vectors [m]; tri_id (G,) int32: the global
    triangle id of each sorted triangle. Binary tree: node_box (N, 6)
    float32 min x, y, z, max x, y, z [m]; node_first / node_count (N,)
    int32; node_near (N,) int8 which child a packet of rays visits first
    (see ``_near_side``); depth: the tree's depth (root = 1). Wide tree (what
    the caster walks, see ``_collapse``): root_box (6,) float64 [m],
    wide_box (float32), wide_child, wide_order, leaf_first, leaf_count, and
    the same packed as the caster reads it: wide_record (W, 32) int32 and
    its float32 view wide_record_f (``pack_records``).
    """

    def __init__(self, triangles: np.ndarray, triangle_ids: np.ndarray) -> None:
        tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        ids = np.asarray(triangle_ids, dtype=np.int32).reshape(-1)
        if len(ids) != len(tri):
            raise ValueError(f"{len(tri)} triangles but {len(ids)} ids")
        packed = np.empty((len(tri), 9), dtype=np.float32)
        packed[:, 0:3] = tri[:, 0]
        packed[:, 3:6] = tri[:, 1] - tri[:, 0]
        packed[:, 6:9] = tri[:, 2] - tri[:, 0]
        # the corners the ray/triangle test sees (float32 corner + float32 edges), exactly in float64
        a = packed[:, 0:3].astype(np.float64)
        corners = np.stack([a, a + packed[:, 3:6], a + packed[:, 6:9]], axis=1)
        tri_box = np.ascontiguousarray(np.concatenate([corners.min(axis=1), corners.max(axis=1)], axis=1))
        centroid = np.ascontiguousarray(corners.mean(axis=1))
        if len(tri):
            order, box, first, count, depth = _build(tri_box, centroid)
        else:
            order = np.zeros(0, np.int64)
            box = np.array([[np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf]])
            first, count = np.zeros(1, np.int64), np.zeros(1, np.int64)
            depth = 1
        self.tri = np.ascontiguousarray(packed[order])
        self.tri_id = np.ascontiguousarray(ids[order])
        pad = np.concatenate([np.full(3, -BOX_PAD_M), np.full(3, BOX_PAD_M)])
        self.node_box = np.ascontiguousarray((box + pad).astype(np.float32))
        self.node_first = first.astype(np.int32)
        self.node_count = count.astype(np.int32)
        self.node_near = _near_side(self.node_box, self.node_first, self.node_count)
        self.depth = int(depth)
        self.root_box = self.node_box[0].astype(np.float64)
        if len(tri):
            (self.wide_box, self.wide_child, self.wide_order, self.leaf_first,
             self.leaf_count) = _collapse(self.node_box, self.node_first.astype(np.int64),
                                          self.node_count.astype(np.int64), self.node_near)
            self.wide_box = self.wide_box.astype(np.float32)
        else:                 # one wide node of unused slots (the caster does not walk an empty tree)
            self.wide_box = np.full((1, 6 * WIDTH), FAR_M, np.float32)
            self.wide_child = -1 - np.arange(WIDTH, dtype=np.int32)[None, :]
            self.wide_order = np.full((1, 8), 0b11100100, np.int32)
            self.leaf_first = np.zeros(WIDTH, np.int32)
            self.leaf_count = np.zeros(WIDTH, np.int32)
        self.anchor = (0.5 * (self.root_box[:3] + self.root_box[3:]) if len(tri)
                       else np.zeros(3))   # [m]; the records' boxes are relative to it
        self.wide_record = pack_records(self.wide_box, self.wide_child, self.wide_order, self.leaf_first,
                                        self.leaf_count, self.anchor)
        self.wide_record_f = self.wide_record.view(np.float32)

    @property
    def node_total(self) -> int:
        """Number of nodes of the binary tree (leaves and inner nodes)."""
        return len(self.node_first)

    @property
    def wide_total(self) -> int:
        """Number of inner nodes of the 4-wide tree."""
        return len(self.wide_child)


def _aligned_int32(rows: int, cols: int, alignment_bytes: int = 64) -> np.ndarray:
    """A zeroed C-contiguous (rows, cols) int32 array whose first byte lies on an ``alignment_bytes`` boundary."""
    spare = alignment_bytes // 4
    flat = np.zeros(rows * cols + spare, np.int32)
    skip = (-flat.ctypes.data % alignment_bytes) // 4
    return flat[skip:skip + rows * cols].reshape(rows, cols)


def pack_records(wide_box: np.ndarray, wide_child: np.ndarray, wide_order: np.ndarray, leaf_first: np.ndarray,
                 leaf_count: np.ndarray, anchor: np.ndarray) -> np.ndarray:
    """The caster's view of the wide tree: one 128-byte record per wide node, (W, RECORD_WORDS) int32.

    Why: a visit then reads two cache lines (boxes, child references and
    visiting orders side by side) instead of lines of three arrays, and a
    leaf's triangle range comes with its reference instead of from two more
    arrays. Words 0..23 hold ``wide_box`` minus ``anchor`` (3,) [m] (float32
    bits: read them through a float32 view; unused slots keep ``FAR_M``):
    coordinates near 0 keep the caster's float32 rounding small wherever
    the farm lies in the world; 24..27 the child references: ``wide_child`` for an inner
    child (>= 0), else -1 - (first << LEAF_COUNT_BITS | count) of its leaf;
    word 28 + octant // 4, byte octant % 4 the 8-bit ``wide_order`` code.
    """
    n_wide = wide_box.shape[0]
    if np.any(leaf_count >= 1 << LEAF_COUNT_BITS) or np.any(leaf_count < 0):
        raise ValueError(f"a leaf holds {int(leaf_count.max())} triangles; the record packs at most "
                         f"{(1 << LEAF_COUNT_BITS) - 1}")
    if len(leaf_first) and int(leaf_first.max()) >= 1 << (31 - LEAF_COUNT_BITS):
        raise ValueError(f"{int(leaf_first.max())} triangles are too many for the record's leaf references")
    if np.any(wide_order >= 256) or np.any(wide_order < 0):
        raise ValueError("wide_order codes must fit one byte")
    record = _aligned_int32(n_wide, RECORD_WORDS)
    boxes = wide_box.astype(np.float64).reshape(n_wide, 6, WIDTH)
    used = boxes[:, 0:1, :] < FAR_M
    relative = boxes - np.tile(np.asarray(anchor, np.float64), 2)[None, :, None]
    boxes = np.where(used, relative, FAR_M).astype(np.float32).reshape(n_wide, 6 * WIDTH)
    record[:, :RECORD_CHILD] = boxes.view(np.int32)
    child = wide_child.astype(np.int64)
    leaf = np.maximum(-1 - child, 0)
    packed_leaf = (leaf_first.astype(np.int64)[leaf] << LEAF_COUNT_BITS) | leaf_count.astype(np.int64)[leaf]
    record[:, RECORD_CHILD:RECORD_CHILD + WIDTH] = np.where(child >= 0, child, -1 - packed_leaf)
    order = wide_order.astype(np.int64).reshape(n_wide, 2, 4) << (8 * np.arange(4))
    record[:, RECORD_ORDER:RECORD_ORDER + 2] = order.sum(axis=2).astype(np.uint32).view(np.int32)
    return record


def _near_side(box: np.ndarray, first: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Per internal node 2 * axis + (1 if the right child lies lower along axis else 0), 0 for leaves.

    The axis is the one along which the children's box centres lie
    farthest apart; a packet looking towards +axis visits the lower child
    first. Only the order of the visits depends on it, not the hits.
    """
    code = np.zeros(len(first), dtype=np.int8)
    internal = np.flatnonzero(count == 0) if len(first) > 1 else np.zeros(0, np.int64)
    left = first[internal]
    centre_left = 0.5 * (box[left, :3].astype(np.float64) + box[left, 3:])
    centre_right = 0.5 * (box[left + 1, :3].astype(np.float64) + box[left + 1, 3:])
    gap = centre_right - centre_left
    axis = np.argmax(np.abs(gap), axis=1)
    code[internal] = 2 * axis + (gap[np.arange(len(axis)), axis] < 0.0)
    return code

