"""The RGB-D camera's images from the rasteriser's buffers: colour, labels, ground and sky, point cloud.

``raster.draw_plants`` leaves, per worker thread, buffers of inverse depth
1/z and global triangle id; a frame is then made (``FastRasterCamera.render``):

1. ``compose_image`` (parallel over blocks of rows): per row the threads'
   samples are merged first (``_nearest_of_threads``: the nearest wins, one
   tight loop of selects per thread instead of a branchy loop over the
   threads per pixel; the thread buffers are cleared on the way); then per
   pixel (``_compose_row``) the winning triangle id gives colour,
   SemanticClass and plant id, and pixels without a triangle get the
   ground or sky as
   ``SensorScene.ground_and_sky`` computes them (plane z = 0 with the
   bilinear-sampled soil texture, tiled by ``tile_texture``, weights in
   1/256 steps, the three channels blended in 16-bit lanes of one integer;
   sky gradient over the ray elevation).
2. ``fill_cloud_xyzrgb``: the depth point cloud in one pass over the
   pixels, straight into PointCloud2's x, y, z, rgb byte layout (into
   buffers with room for every pixel; the caller keeps the first N rows).

Pixel (col, row) is the sample point u = col, v = row of the pinhole model
of ``camera.CameraModel``, as in ``raster``.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True, inline="always")
def _reflect(i, n):  # pragma: no cover
    """OpenCV BORDER_REFLECT index (fedcba|abcdef|fedcba) for any integer i."""
    period = 2 * n
    i = i % period
    if i < 0:
        i += period
    if i >= n:
        i = period - 1 - i
    return i


TILE = 8    # texture tile edge [texels]
_LANE_MASK_R_B = 0x0000FFFF0000FFFF     # the red and blue lanes of a spread texel (bits 0-15 and 32-47)
_ROUND_R_B = 0x0000800000008000         # 1/2 in 1/65536 steps in the red and blue lanes
_ROWS_PER_ITEM = 8                      # image rows per parallel work item of compose_image


def tile_texture(image: np.ndarray) -> np.ndarray:
    """(h, w, 3) uint8 -> (ceil(h / 8), ceil(w / 8), 64) int64, the texture layout of ``compose_image``.

    Each texel is *spread* into three 16-bit lanes, r | g << 16 | b << 32,
    so that ``compose_image`` blends all three channels with one integer
    multiplication per texel (the lanes leave room for the weighted sums),
    and the texture is stored in 8 x 8 tiles (row-major inside a tile,
    tiles row-major), so that texels near each other on the ground are
    near each other in memory whatever the direction the camera looks in
    (row-major storage costs a cache and TLB miss per pixel when an image
    row runs along a texture column).
    """
    image = np.asarray(image, dtype=np.int64)
    h, w = image.shape[:2]
    ty, tx = -(-h // TILE), -(-w // TILE)
    spread = np.zeros((ty * TILE, tx * TILE), dtype=np.int64)
    spread[:h, :w] = image[..., 0] | (image[..., 1] << 16) | (image[..., 2] << 32)
    return np.ascontiguousarray(spread.reshape(ty, TILE, tx, TILE).transpose(0, 2, 1, 3).reshape(ty, tx, TILE * TILE))


@njit(cache=True, nogil=True, inline="always")
def _texel_index(row, col, tiles_x):  # pragma: no cover
    """Flat index of texel (row, col) in the tiled layout of ``tile_texture``."""
    return (((row >> 3) * tiles_x + (col >> 3)) << 6) | ((row & 7) << 3) | (col & 7)


@njit(cache=True, nogil=True, inline="always")
def _texel_quad(tex_flat, ix, iy, tiles_x, tile_row, tex_w, tex_h):  # pragma: no cover
    """Texels (iy, ix), (iy, ix + 1), (iy + 1, ix), (iy + 1, ix + 1) of the flat tiled texture.

    Outside the texture (or on its last row / column) the indices are
    mirrored as OpenCV's BORDER_REFLECT does. tiles_x: tiles per row of
    tiles; tile_row: texels in one row of tiles.
    """
    if 0 <= ix and ix + 1 < tex_w and 0 <= iy and iy + 1 < tex_h:   # inside: no border rule needed
        # unsigned indices: numba adds no wrap-around of negative ones
        i00 = np.uint64(_texel_index(iy, ix, tiles_x))
        # the right neighbour: next in the tile's row, or the first of the next tile's row
        right = np.uint64(1) if (ix & 7) != 7 else np.uint64(57)
        # the lower one: next row of the tile, or the first row of the tile below
        down = np.uint64(8) if (iy & 7) != 7 else np.uint64(tile_row - 56)
        return tex_flat[i00], tex_flat[i00 + right], tex_flat[i00 + down], tex_flat[i00 + down + right]
    c0, c1 = _reflect(ix, tex_w), _reflect(ix + 1, tex_w)
    r0, r1 = _reflect(iy, tex_h), _reflect(iy + 1, tex_h)
    return (tex_flat[np.uint64(_texel_index(r0, c0, tiles_x))], tex_flat[np.uint64(_texel_index(r0, c1, tiles_x))],
            tex_flat[np.uint64(_texel_index(r1, c0, tiles_x))], tex_flat[np.uint64(_texel_index(r1, c1, tiles_x))])


@njit(cache=True, nogil=True, inline="always")
def _bilinear_spread(p00, p01, p10, p11, ax, ay):  # pragma: no cover
    """Blend four spread texels (r | g << 16 | b << 32) with weights in 1/256 steps; returns r, g, b.

    ax, ay in 0..256: the weight of the right (p01, p11) and of the lower
    (p10, p11) texels. The same integers as blending each channel with the
    product weights (256 - ay)(256 - ax), ... and rounding (+ 2^15) >> 16:
    first along x (each lane <= 255 * 256 < 2^16: no carry between lanes),
    then along y with red and blue in 32-bit lanes (<= 2^24) and green alone.
    """
    bx, by = 256 - ax, 256 - ay
    top = p00 * bx + p01 * ax
    bottom = p10 * bx + p11 * ax
    rb = (top & _LANE_MASK_R_B) * by + (bottom & _LANE_MASK_R_B) * ay + _ROUND_R_B
    g = ((top >> 16) & 0xFFFF) * by + ((bottom >> 16) & 0xFFFF) * ay + 32768
    return (rb >> 16) & 255, g >> 16, (rb >> 48) & 255


@njit(parallel=True, cache=True, nogil=True)
def compose_image(zbuf, ibuf, g_rgb, g_semantic, g_plant, rot_wo, t_wo, fx, fy, cx, cy, near, far, texture,
             tex_w, tex_h, tex_x0, tex_y0, tex_res_x, tex_res_y, sky_lut, ground_class, sky_class,
             out_rgb, out_depth, out_sem, out_plant):  # pragma: no cover
    """Merge the thread buffers, colour by triangle id, paint ground and sky; clears zbuf.

    rot_wo (3, 3), t_wo (3,): world_T_optical. Depth outside [near, far]
    becomes NaN (sky: NaN, semantic SKY). texture: the soil texture of
    tex_w x tex_h texels in the tiled, spread layout of ``tile_texture``.
    """
    _, height, width = zbuf.shape
    tiles_x = texture.shape[1]
    tile_row = tiles_x * TILE * TILE                    # texels in one row of tiles
    tex_flat = texture.reshape(texture.size)           # the same texels, one index
    inv_fx, inv_rx, inv_ry = 1.0 / fx, 1.0 / tex_res_x, 1.0 / tex_res_y
    n_items = (height + _ROWS_PER_ITEM - 1) // _ROWS_PER_ITEM
    for item in prange(n_items):
        nearest_w = np.empty(width, np.float32)       # per pixel of a row: the largest 1/z of the threads
        nearest_id = np.empty(width, np.int32)        # ... and its triangle id (-1: none)
        for y in range(item * _ROWS_PER_ITEM, min(height, (item + 1) * _ROWS_PER_ITEM)):
            _nearest_of_threads(zbuf, ibuf, y, nearest_w, nearest_id)
            _compose_row(y, nearest_w, nearest_id, g_rgb, g_semantic, g_plant, rot_wo, t_wo, fy, cx, cy, near, far,
                         tex_flat, tiles_x, tile_row, tex_w, tex_h, tex_x0, tex_y0, inv_fx, inv_rx, inv_ry, sky_lut,
                         ground_class, sky_class, out_rgb, out_depth, out_sem, out_plant)


@njit(cache=True, nogil=True, inline="always")
def _nearest_of_threads(zbuf, ibuf, y, nearest_w, nearest_id):  # pragma: no cover
    """Row y of the threads' buffers merged: per pixel the largest 1/z (0 = none) and its id; clears the row.

    On equal 1/z the lower thread wins. One loop of selects per thread over the row (LLVM keeps it
    scalar, but it has no data-dependent branch).
    """
    n_threads, _, width = zbuf.shape
    for x in range(width):
        nearest_w[x] = 0.0
        nearest_id[x] = -1
    for k in range(n_threads):
        zrow = zbuf[k, y]
        irow = ibuf[k, y]
        for x in range(width):
            w = zrow[x]
            nearer = w > nearest_w[x]
            nearest_w[x] = w if nearer else nearest_w[x]
            nearest_id[x] = irow[x] if nearer else nearest_id[x]
            zrow[x] = 0.0


@njit(cache=True, nogil=True, inline="always")
def _compose_row(y, nearest_w, nearest_id, g_rgb, g_semantic, g_plant, rot_wo, t_wo, fy, cx, cy, near, far, tex_flat,
                 tiles_x, tile_row, tex_w, tex_h, tex_x0, tex_y0, inv_fx, inv_rx, inv_ry, sky_lut, ground_class,
                 sky_class, out_rgb, out_depth, out_sem, out_plant):  # pragma: no cover
    """Image row y of ``compose_image`` from the row's merged nearest samples (``_nearest_of_threads``).

    tex_flat: the tiled texture as one flat array; tiles_x tiles per row of
    tiles, tile_row texels in one row of tiles; inv_*: 1 / fx, 1 / the
    texture's resolution along x and y.
    """
    cam_h = t_wo[2]
    width = nearest_w.shape[0]
    ry = (y - cy) / fy
    # world ray of pixel (x, y) = row_* + x * step_* (affine in x)
    row_x = rot_wo[0, 0] * (-cx * inv_fx) + rot_wo[0, 1] * ry + rot_wo[0, 2]
    row_y = rot_wo[1, 0] * (-cx * inv_fx) + rot_wo[1, 1] * ry + rot_wo[1, 2]
    row_z = rot_wo[2, 0] * (-cx * inv_fx) + rot_wo[2, 1] * ry + rot_wo[2, 2]
    step_x, step_y, step_z = rot_wo[0, 0] * inv_fx, rot_wo[1, 0] * inv_fx, rot_wo[2, 0] * inv_fx
    for x in range(width):
        gid = nearest_id[x]
        if gid >= 0:
            d = 1.0 / np.float64(nearest_w[x])
            out_depth[y, x] = d if near <= d <= far else np.nan
            out_rgb[y, x, 0] = g_rgb[gid, 0]
            out_rgb[y, x, 1] = g_rgb[gid, 1]
            out_rgb[y, x, 2] = g_rgb[gid, 2]
            out_sem[y, x] = g_semantic[gid]
            out_plant[y, x] = g_plant[gid]
            continue
        out_plant[y, x] = -1
        # ray K^-1 (x, y, 1) in the world
        dxw = row_x + x * step_x
        dyw = row_y + x * step_y
        dzw = row_z + x * step_z
        if dzw < -1e-9 and cam_h > 0.0:
            d = -cam_h / dzw
            out_depth[y, x] = d if near <= d <= far else np.nan
            out_sem[y, x] = ground_class
            gx = (t_wo[0] + d * dxw - tex_x0) * inv_rx
            gy = (t_wo[1] + d * dyw - tex_y0) * inv_ry
            if not (abs(gx) < 1e9 and abs(gy) < 1e9):
                gx, gy = 0.0, 0.0
            fxi = math.floor(gx)
            fyi = math.floor(gy)
            ix, iy = int(fxi), int(fyi)
            # bilinear weights in 1/256 steps (OpenCV's warps use 1/32)
            ax = int((gx - fxi) * 256.0)
            ay = int((gy - fyi) * 256.0)
            p00, p01, p10, p11 = _texel_quad(tex_flat, ix, iy, tiles_x, tile_row, tex_w, tex_h)
            r, g, b = _bilinear_spread(p00, p01, p10, p11, ax, ay)
            out_rgb[y, x, 0] = np.uint8(r)
            out_rgb[y, x, 1] = np.uint8(g)
            out_rgb[y, x, 2] = np.uint8(b)
        else:
            out_depth[y, x] = np.nan
            out_sem[y, x] = sky_class
            rx = (x - cx) * inv_fx
            norm = math.sqrt(rx * rx + ry * ry + 1.0)
            s = min(1.0, max(0.0, dzw / norm))
            idx = int(s * 255.0)
            out_rgb[y, x, 0] = sky_lut[idx, 0]
            out_rgb[y, x, 1] = sky_lut[idx, 1]
            out_rgb[y, x, 2] = sky_lut[idx, 2]


@njit(cache=True, nogil=True)
def fill_cloud_xyzrgb(depth, rgb, ray_x, ray_y, stride, min_m, max_m, out_f, out_u, out_rgb):  # pragma: no cover
    """The depth cloud straight into PointCloud2's x, y, z, rgb layout (16 bytes a point); returns its size N.

    The pixels kept: every stride-th in u and v whose depth lies in
    [min_m, max_m] (NaN fails), in row-major order: x = ray_x[col] * z,
    y = ray_y[row] * z with ray_x = (u - cx) / fx, ray_y = (v - cy) / fy
    (float32, as numpy computes them), in the optical frame [m].

    out_f (M, 4) float32 and out_u (M, 4) uint32 are two views of the same
    memory, M >= N (room for every stride-th pixel): x, y, z go to
    out_f[:N, :3], PCL's packed colour 0x00RRGGBB to out_u[:N, 3]; out_rgb
    (M, 3) uint8 gets the colours unpacked.
    """
    height, width = depth.shape
    i = 0
    for y in range(0, height, stride):
        ry = ray_y[y]
        for x in range(0, width, stride):
            z = depth[y, x]
            if z >= min_m and z <= max_m:
                out_f[i, 0] = ray_x[x] * z
                out_f[i, 1] = ry * z
                out_f[i, 2] = z
                r, g, b = rgb[y, x, 0], rgb[y, x, 1], rgb[y, x, 2]
                out_u[i, 3] = (np.uint32(r) << 16) | (np.uint32(g) << 8) | np.uint32(b)
                out_rgb[i, 0] = r
                out_rgb[i, 1] = g
                out_rgb[i, 2] = b
                i += 1
    return i
