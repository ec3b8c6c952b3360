"""Numba z-buffer rasteriser for the RGB-D cameras.

Why: pybullet's TinyRenderer spends 100-900 ms on a frame of the default
farm; the farm is a few hundred thousand small, flat-coloured triangles, which
a plain compiled rasteriser draws in a few milliseconds.

How a frame is made (``FastRasterCamera.render``):

1. the visible plants come from ``SensorScene.plants_in_view_depth``
   (bounding spheres against the view frustum, as the pybullet path does);
   ``CameraModel`` picks each one's level of detail (the full model, the
   middle levels of ``geometry.simplified_model_arrays`` or the far proxies
   of ``geometry.proxy_model_arrays``: the coarsest whose error bound
   projects to at most ``lod_max_error_px``);
2. ``draw_plants`` (parallel): each worker thread takes every n-th visible
   plant, moves the plant's model vertices into the optical frame (one 3x4
   transform per plant), skips faces whose screen box holds no sample point
   (most faces of a far plant), drops back faces (counter-clockwise faces
   seen from behind, the culling TinyRenderer does; a two-sided leaf's pair
   of faces is drawn once, with the id of the side that faces the camera),
   clips faces that cross the near plane (a face with
   corners on both sides becomes one or two triangles) and rasterises them
   into its *own* buffers of inverse depth 1/z and global triangle id. Own
   buffers per thread mean no write races; 1/z is affine in the pixel
   coordinates, so it is interpolated exactly and gives the metric depth
   along the optical axis of the triangle's plane;
3. the image from the buffers: ``image_compose.compose_image`` (ground, sky, colour,
   labels) and ``image_compose.fill_cloud_xyzrgb`` (the point cloud).

Sampling convention: pixel (col, row) is the point u = col, v = row of the
pinhole model u = fx x / z + cx, v = fy y / z + cy with the intrinsics of
``camera.CameraModel`` (cx = (W - 1) / 2). A pixel is covered when its
sample point lies inside or on the edge of a triangle.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True, inline="always")
def _fill(u0, v0, w0, u1, v1, w1, u2, v2, w2, area, x_lo, x_hi, y_lo, y_hi, gid, zb, ib, w_min, w_max):  # pragma: no cover
    """Depth-tested fill of a screen triangle with a non-zero signed area and a non-empty sample box."""
    inv = 1.0 / area
    # barycentric weights as affine functions b_i(x, y) = ax_i x + ay_i y + c_i
    ax0, ay0 = (v1 - v2) * inv, (u2 - u1) * inv
    c0 = (u1 * v2 - v1 * u2) * inv
    ax1, ay1 = (v2 - v0) * inv, (u0 - u2) * inv
    c1 = (u2 * v0 - v2 * u0) * inv
    ax2, ay2 = (v0 - v1) * inv, (u1 - u0) * inv
    c2 = (u0 * v1 - v0 * u1) * inv
    wx = ax0 * w0 + ax1 * w1 + ax2 * w2
    wy = ay0 * w0 + ay1 * w1 + ay2 * w2
    wc = c0 * w0 + c1 * w1 + c2 * w2
    eps = 1e-9
    # the row spans need -r / ax per edge and row: one division per edge here, multiplications per row
    k0 = -1.0 / ax0 if abs(ax0) > eps else 0.0
    k1 = -1.0 / ax1 if abs(ax1) > eps else 0.0
    k2 = -1.0 / ax2 if abs(ax2) > eps else 0.0
    for y in range(y_lo, y_hi + 1):
        # span of x where all three weights are >= 0 on this row
        lo = float(x_lo)
        hi = float(x_hi)
        r0 = ay0 * y + c0
        r1 = ay1 * y + c1
        r2 = ay2 * y + c2
        empty = False
        for ax, r, k in ((ax0, r0, k0), (ax1, r1, k1), (ax2, r2, k2)):
            if ax > eps:
                lo = max(lo, r * k)
            elif ax < -eps:
                hi = min(hi, r * k)
            elif r < -eps:
                empty = True
        if empty:
            continue
        xa = int(math.ceil(lo - 1e-7))
        xb = int(math.floor(hi + 1e-7))
        if xa < x_lo:
            xa = x_lo
        if xb > x_hi:
            xb = x_hi
        wrow = wy * y + wc
        uy = np.uint64(y)                 # unsigned pixel indices: no wrap-around code for negative ones
        for x in range(xa, xb + 1):
            # exact inside test (the span may be off by rounding at its ends)
            if ax0 * x + r0 < -eps or ax1 * x + r1 < -eps or ax2 * x + r2 < -eps:
                continue
            w = wx * x + wrow
            ux = np.uint64(x)
            if w > zb[uy, ux] and w_min <= w <= w_max:
                zb[uy, ux] = w
                ib[uy, ux] = gid


@njit(cache=True, nogil=True, inline="always")
def _sample_box(u0, v0, u1, v1, u2, v2, width, height):  # pragma: no cover
    """Integer sample points (x_lo..x_hi, y_lo..y_hi) inside the screen box of a triangle (may be empty)."""
    x_lo = max(0, int(math.ceil(min(u0, u1, u2))))
    x_hi = min(width - 1, int(math.floor(max(u0, u1, u2))))
    y_lo = max(0, int(math.ceil(min(v0, v1, v2))))
    y_hi = min(height - 1, int(math.floor(max(v0, v1, v2))))
    return x_lo, x_hi, y_lo, y_hi


@njit(cache=True, nogil=True, inline="always")
def _raster_triangle(u0, v0, w0, u1, v1, w1, u2, v2, w2, gid, zb, ib, w_min, w_max):  # pragma: no cover
    """Depth-tested fill of one screen triangle; w = 1/z at the corners."""
    height, width = zb.shape
    area = (u1 - u0) * (v2 - v0) - (v1 - v0) * (u2 - u0)
    if area == 0.0 or not math.isfinite(area):
        return
    x_lo, x_hi, y_lo, y_hi = _sample_box(u0, v0, u1, v1, u2, v2, width, height)
    if x_lo > x_hi or y_lo > y_hi:
        return
    _fill(u0, v0, w0, u1, v1, w1, u2, v2, w2, area, x_lo, x_hi, y_lo, y_hi, gid, zb, ib, w_min, w_max)


@njit(cache=True, nogil=True, inline="always")
def _facing_id(from_behind, fi, gb, draw_local, draw_twin):  # pragma: no cover
    """Global triangle id of the side of drawn face ``fi`` that faces the camera (gb: the plant's first id):
    its reverse-wound twin when seen from behind, -1 when it has none (a one-sided face: culled)."""
    if from_behind:
        twin = draw_twin[fi]
        return -1 if twin < 0 else gb + twin
    return gb + draw_local[fi]


@njit(cache=True, nogil=True, inline="always")
def _project_draw(p, fx, fy, cx, cy, gid, zb, ib, w_min, w_max):  # pragma: no cover
    """Project a camera-frame triangle p (3, 3) with z > 0 and draw it."""
    iz0, iz1, iz2 = 1.0 / p[0, 2], 1.0 / p[1, 2], 1.0 / p[2, 2]
    _raster_triangle(fx * p[0, 0] * iz0 + cx, fy * p[0, 1] * iz0 + cy, iz0,
                     fx * p[1, 0] * iz1 + cx, fy * p[1, 1] * iz1 + cy, iz1,
                     fx * p[2, 0] * iz2 + cx, fy * p[2, 1] * iz2 + cy, iz2, gid, zb, ib, w_min, w_max)


@njit(cache=True, nogil=True)
def _clip_near_and_draw(ax, ay, az, bx, by, bz, cx_, cy_, cz, near, fx, fy, cx, cy, gid, zb, ib, w_min,
                        w_max):  # pragma: no cover
    """Clip triangle (a, b, c) (camera frame [m]) to z >= near and draw the 1-2 pieces."""
    src = np.empty((3, 3))
    src[0, 0], src[0, 1], src[0, 2] = ax, ay, az
    src[1, 0], src[1, 1], src[1, 2] = bx, by, bz
    src[2, 0], src[2, 1], src[2, 2] = cx_, cy_, cz
    poly = np.empty((4, 3))
    n = 0
    for i in range(3):
        p, q = src[i], src[(i + 1) % 3]
        p_in, q_in = p[2] >= near, q[2] >= near
        if p_in:
            poly[n] = p
            n += 1
        if p_in != q_in:
            s = (near - p[2]) / (q[2] - p[2])
            poly[n] = p + s * (q - p)
            poly[n, 2] = near
            n += 1
    tri = np.empty((3, 3))
    for k in range(1, n - 1):
        tri[0] = poly[0]
        tri[1] = poly[k]
        tri[2] = poly[k + 1]
        _project_draw(tri, fx, fy, cx, cy, gid, zb, ib, w_min, w_max)


@njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def draw_plants(visible, vis_model, vis_gbase, plant_pose, model_vbase, model_vcount, draw_base, draw_count,
                 model_xyz, draw_faces, draw_local, draw_twin, rot, trans, fx, fy, cx, cy, near, far,
                 zbuf, ibuf, scratch):  # pragma: no cover
    """Rasterise the visible plants into per-thread buffers zbuf/ibuf (T, H, W).

    visible (n,) plant indices; vis_model (n,) the model (level of detail)
    to draw each with; vis_gbase (n,) its first global triangle id.
    A face seen from behind is skipped unless it has a reverse-wound twin
    (two-sided leaf), whose id it then takes (see ``InstancedPlants``).
    For a face in front of the near plane the back-face test is the sign of
    its screen area (the same sign as the camera-frame test n . a for
    z > 0), done after the cheaper test whether its screen box holds any
    sample point at all: most faces of a far plant hold none.

    model_xyz (3, sum V): the plant-local vertices, one coordinate per row.
    rot (3, 3), trans (3,): optical_T_world. scratch (T, 6, max verts)
    holds each thread's transformed vertices as rows x, y, z, u, v, 1/z.
    The vertex loop has no branch and reads and writes with unit stride,
    so LLVM vectorises it (4 vertices per AVX2 instruction); u, v and 1/z
    of a vertex behind the near plane are garbage (z may even be 0: hence
    error_model "numpy", a division by zero gives inf instead of raising)
    and are read only for faces with every corner at z >= near.
    """
    n_threads, height, width = zbuf.shape
    w_min, w_max = 1.0 / far, 1.0 / near
    for k in prange(n_threads):
        zb, ib, sc = zbuf[k], ibuf[k], scratch[k]
        sx, sy, sz, su, sv, sw = sc[0], sc[1], sc[2], sc[3], sc[4], sc[5]
        for j in range(k, visible.shape[0], n_threads):
            p = visible[j]
            m = vis_model[j]
            px, py, co, si = plant_pose[p, 0], plant_pose[p, 1], plant_pose[p, 2], plant_pose[p, 3]
            # optical_T_plant = optical_T_world @ world_T_plant (yaw about z, then x, y)
            m00 = rot[0, 0] * co + rot[0, 1] * si
            m01 = -rot[0, 0] * si + rot[0, 1] * co
            m10 = rot[1, 0] * co + rot[1, 1] * si
            m11 = -rot[1, 0] * si + rot[1, 1] * co
            m20 = rot[2, 0] * co + rot[2, 1] * si
            m21 = -rot[2, 0] * si + rot[2, 1] * co
            m02, m12, m22 = rot[0, 2], rot[1, 2], rot[2, 2]
            t0 = rot[0, 0] * px + rot[0, 1] * py + trans[0]
            t1 = rot[1, 0] * px + rot[1, 1] * py + trans[1]
            t2 = rot[2, 0] * px + rot[2, 1] * py + trans[2]
            vb = model_vbase[m]
            nv = model_vcount[m]
            mx, my, mz = model_xyz[0, vb:vb + nv], model_xyz[1, vb:vb + nv], model_xyz[2, vb:vb + nv]
            for i in range(nv):
                lx, ly, lz = mx[i], my[i], mz[i]
                x = m00 * lx + m01 * ly + m02 * lz + t0
                y = m10 * lx + m11 * ly + m12 * lz + t1
                z = m20 * lx + m21 * ly + m22 * lz + t2
                iz = 1.0 / z
                sx[i] = x
                sy[i] = y
                sz[i] = z
                su[i] = fx * x * iz + cx
                sv[i] = fy * y * iz + cy
                sw[i] = iz
            fb = draw_base[m]
            gb = vis_gbase[j]
            for f in range(draw_count[m]):
                # unsigned indices: numba adds no wrap-around code for negative ones
                fi = np.uint64(fb + f)
                ia = np.uint64(draw_faces[fi, 0] - vb)
                ib_ = np.uint64(draw_faces[fi, 1] - vb)
                ic = np.uint64(draw_faces[fi, 2] - vb)
                za, zb_, zc = sz[ia], sz[ib_], sz[ic]
                if za >= near and zb_ >= near and zc >= near:
                    if za > far and zb_ > far and zc > far:
                        continue
                    ua, va, ub, vb_, uc, vc = su[ia], sv[ia], su[ib_], sv[ib_], su[ic], sv[ic]
                    x_lo, x_hi, y_lo, y_hi = _sample_box(ua, va, ub, vb_, uc, vc, width, height)
                    if x_lo > x_hi or y_lo > y_hi:
                        continue
                    area = (ub - ua) * (vc - va) - (vb_ - va) * (uc - ua)
                    if area == 0.0 or not math.isfinite(area):
                        continue
                    gid = _facing_id(area > 0.0, fi, gb, draw_local, draw_twin)     # area > 0: seen from behind
                    if gid < 0:
                        continue
                    _fill(ua, va, sw[ia], ub, vb_, sw[ib_], uc, vc, sw[ic], area, x_lo, x_hi, y_lo, y_hi,
                          gid, zb, ib, w_min, w_max)
                    continue
                if za < near and zb_ < near and zc < near:
                    continue
                e1x, e1y, e1z = sx[ib_] - sx[ia], sy[ib_] - sy[ia], zb_ - za
                e2x, e2y, e2z = sx[ic] - sx[ia], sy[ic] - sy[ia], zc - za
                nx = e1y * e2z - e1z * e2y
                ny = e1z * e2x - e1x * e2z
                nz = e1x * e2y - e1y * e2x
                gid = _facing_id(nx * sx[ia] + ny * sy[ia] + nz * za >= 0.0, fi, gb, draw_local, draw_twin)
                if gid < 0:
                    continue
                _clip_near_and_draw(sx[ia], sy[ia], za, sx[ib_], sy[ib_], zb_, sx[ic], sy[ic], zc, near, fx, fy, cx,
                                    cy, gid, zb, ib, w_min, w_max)
