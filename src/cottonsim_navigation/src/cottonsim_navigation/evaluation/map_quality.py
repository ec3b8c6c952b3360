"""Quality of a built (SLAM) occupancy map against the ground-truth occupancy of the farm.

Why: the paper's map-based mode first maps the farm with gmapping; whether that
map is good enough for AMCL is a question of (a) how well the plant cells it
marks coincide with the real plants and (b) how much the map is rotated or
shifted (a rotated map bends every lane of the route). Both are measured here
without ROS, from two occupancy grids (nav_msgs/OccupancyGrid values: -1
unknown, 0 free, 100 occupied; ``grid[iy, ix]`` with row 0 at the origin).

Method:

1. Alignment. The map frame and the truth frame are meant to be the same (the
   Home frame) but SLAM leaves a small rigid error. We search the rigid
   transform ``p_truth = R(theta) p_map + t`` that maximises the plant IoU
   over the observed area (step 2, on truth cells): ``theta`` on a coarse then
   a fine grid of angles, and for each angle every whole-cell ``t`` in a window
   at once (``|M & T|`` and ``|T & observed|`` for all shifts are two
   cross-correlations, done with FFTs). The overlap ``|M & T|`` alone is not
   enough: plants repeat every plant spacing along a row, so a map of part of a
   row overlaps the truth as well one spacing further on as in place (only the
   row's end tells them apart, by a true plant falling on ground the map saw
   free); the IoU counts that plant, the overlap does not.
2. Scores at the best transform, over the *observed area* (cells the map
   knows, i.e. not -1, resampled into the truth grid): plant IoU
   ``|M & T| / |M | T|`` where M = map-occupied, T = truth-occupied and
   observed; precision ``|M & T| / |M|``; recall ``|M & T| / |T|``. The laser
   only ever sees a plant's surface, the hidden inside stays unknown, so
   restricting to the observed area does not punish what no sensor can see.
   With ``tolerance_m`` > 0 a cell counts as matched when the other grid has
   an occupied cell within that distance (a tolerant IoU: matched cells of
   both grids over all of both, ``(m_M + m_T) / (|M| + |T|)``).

The rotation error is ``|theta|`` in degrees, the translation error ``|t|``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence, Tuple

import numpy as np
from scipy import ndimage
from scipy.signal import fftconvolve

from cottonsim_common.validation import require_fields, require_finite_values, require_instance, require_positive

OCCUPIED_DEFAULT = 65     # OccupancyGrid values >= this are occupied (map_server occupied_thresh 0.65)


@dataclass(frozen=True)
class MapQualityConfig:
    """Parameters of :func:`evaluate_map`.

    max_rotation_deg: rotations searched in [-max, +max] [deg];
    coarse_step_deg: step of the coarse rotation search [deg];
    fine_step_deg: step of the fine search around the coarse best (+/- one coarse step) [deg];
    max_shift_m: translations searched in [-max, +max] along x and y (whole truth cells) [m];
    occupied_value: OccupancyGrid values >= this count as occupied [0..100];
    tolerance_m: a cell is matched when the other grid has an occupied cell this close; 0 = the same cell [m];
    cell_m: score on cells of this size (a block is occupied / observed when any truth-resolution cell in it
        is); 0 = the truth grid's resolution [m]. Plant scale (e.g. 0.25 m) forgives the LiDAR seeing a
        plant's leaves and branches where the truth has its collision volume.
    """

    max_rotation_deg: float = 3.0
    coarse_step_deg: float = 0.25
    fine_step_deg: float = 0.025
    max_shift_m: float = 1.0
    occupied_value: int = OCCUPIED_DEFAULT
    tolerance_m: float = 0.0
    cell_m: float = 0.0

    def __post_init__(self) -> None:
        require_fields(self, non_negative=("max_rotation_deg", "max_shift_m", "tolerance_m", "cell_m"),
                       positive=("coarse_step_deg", "fine_step_deg"))
        if self.fine_step_deg > self.coarse_step_deg:
            raise ValueError(f"fine_step_deg ({self.fine_step_deg}) must not exceed coarse_step_deg "
                             f"({self.coarse_step_deg})")
        if isinstance(self.occupied_value, bool) or not isinstance(self.occupied_value, int) \
                or not 1 <= self.occupied_value <= 100:
            raise ValueError(f"occupied_value must be an integer in [1, 100], got {self.occupied_value!r}")


@dataclass(frozen=True)
class MapQuality:
    """Result of :func:`evaluate_map`.

    iou: plant-cell IoU over the observed area [0..1]; precision, recall [0..1];
    rotation_deg: the best alignment's rotation theta (signed, map -> truth) [deg];
    rotation_error_deg: |rotation_deg| [deg];
    shift_x_m, shift_y_m: the best alignment's translation t [m]; shift_m: |t| [m];
    map_occupied_cells: |M| and truth_occupied_cells: |T| (observed) in truth cells;
    observed_cells: scoring cells the map knows; matched_cells: |M & T| (tolerant when tolerance_m > 0);
    the cell counts are in scoring cells (truth cells, or cell_m blocks).
    """

    iou: float
    precision: float
    recall: float
    rotation_deg: float
    rotation_error_deg: float
    shift_x_m: float
    shift_y_m: float
    shift_m: float
    map_occupied_cells: int
    truth_occupied_cells: int
    observed_cells: int
    matched_cells: int

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _check_grid(name: str, grid, resolution_m, origin) -> Tuple[np.ndarray, float, Tuple[float, float, float]]:
    g = np.asarray(grid)
    if g.ndim != 2 or g.shape[0] < 1 or g.shape[1] < 1:
        raise ValueError(f"{name} grid must be a non-empty 2-D array, got shape {g.shape}")
    if not np.issubdtype(g.dtype, np.integer):
        raise ValueError(f"{name} grid must hold integers (-1 / 0..100), got {g.dtype}")
    resolution_m = require_positive(f"{name} resolution_m", resolution_m)
    origin = require_finite_values(f"{name} origin (x_m, y_m, yaw_rad)", origin, 3)
    return g.astype(np.int16), resolution_m, origin


def _resample(grid: np.ndarray, res: float, origin, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
    """Nearest-cell values of ``grid`` at frame points (qx, qy); -1 outside the grid."""
    ox, oy, oyaw = origin
    c, s = math.cos(oyaw), math.sin(oyaw)
    dx, dy = qx - ox, qy - oy
    lx, ly = c * dx + s * dy, -s * dx + c * dy            # into the grid's own axes
    ix = np.floor(lx / res).astype(np.int64)
    iy = np.floor(ly / res).astype(np.int64)
    inside = (ix >= 0) & (ix < grid.shape[1]) & (iy >= 0) & (iy < grid.shape[0])
    out = np.full(qx.shape, -1, dtype=np.int16)
    out[inside] = grid[iy[inside], ix[inside]]
    return out


def map_on_truth_cells(map_grid, map_resolution_m: float, map_origin: Sequence[float],
                       truth_shape: Tuple[int, int], truth_resolution_m: float,
                       truth_origin: Sequence[float]) -> np.ndarray:
    """The map's values (-1 / 0..100) at the centres of a truth grid's cells, in the frame both origins are
    given in, without any alignment: what a side-by-side figure of map and truth should show (the map's own
    registration errors included). ``truth_shape`` is (rows, cols) of the truth grid."""
    mg, mres, mo = _check_grid("map", map_grid, map_resolution_m, map_origin)
    rows, cols = (int(v) for v in truth_shape)
    if rows < 1 or cols < 1:
        raise ValueError(f"truth_shape must be (rows, cols) >= 1, got {truth_shape!r}")
    _, tres, to = _check_grid("truth", np.zeros((1, 1), dtype=np.int16), truth_resolution_m, truth_origin)
    c, s = math.cos(to[2]), math.sin(to[2])
    jx, jy = np.meshgrid(np.arange(cols) + 0.5, np.arange(rows) + 0.5)
    qx = to[0] + c * jx * tres - s * jy * tres
    qy = to[1] + s * jx * tres + c * jy * tres
    return _resample(mg, mres, mo, qx, qy)


class _Aligner:
    """The map resampled into the truth grid (padded by the shift window) for any rotation."""

    def __init__(self, mgrid, mres, morigin, tgrid, tres, torigin, config: MapQualityConfig):
        self.m = (mgrid, mres, morigin)
        self.config = config
        self.tres = tres
        self.truth_occ = (tgrid >= config.occupied_value)
        self.pad = int(math.ceil(config.max_shift_m / tres))
        h, w = tgrid.shape
        tox, toy, tyaw = torigin
        c, s = math.cos(tyaw), math.sin(tyaw)
        jx, jy = np.meshgrid(np.arange(-self.pad, w + self.pad) + 0.5, np.arange(-self.pad, h + self.pad) + 0.5)
        # centres of the padded truth cells in the common frame
        self.qx = tox + c * jx * tres - s * jy * tres
        self.qy = toy + s * jx * tres + c * jy * tres
        self.kernel = self.truth_occ[::-1, ::-1].astype(np.float32)

    def rotated_map(self, theta_rad: float) -> np.ndarray:
        """Map values at the padded truth cells after rotating the map by theta: map(R^T q)."""
        c, s = math.cos(theta_rad), math.sin(theta_rad)
        px = c * self.qx + s * self.qy
        py = -s * self.qx + c * self.qy
        return _resample(*self.m, px, py)

    def best_shift(self, theta_rad: float) -> Tuple[int, int, float]:
        """(sx, sy, iou): the whole-cell shift of the rotated map with the highest plant IoU over the observed
        area (truth-resolution cells)."""
        rotated = self.rotated_map(theta_rad)
        occ = (rotated >= self.config.occupied_value).astype(np.float32)
        if not occ.any() or not self.truth_occ.any():
            return 0, 0, 0.0
        # overlap[a, b] = sum_q T(q) * M(q + (a, b) - pad): |M & T| when the map moves by (pad - a, pad - b);
        # seen[a, b]: the true plant cells on observed map cells; inside[a, b]: |M| within the truth grid
        overlap = np.rint(fftconvolve(occ, self.kernel, mode="valid"))
        seen = np.rint(fftconvolve((rotated >= 0).astype(np.float32), self.kernel, mode="valid"))
        h, w = self.truth_occ.shape
        csum = np.pad(np.cumsum(np.cumsum(occ, axis=0), axis=1), ((1, 0), (1, 0)))
        inside = csum[h:, w:] - csum[:-h, w:] - csum[h:, :-w] + csum[:-h, :-w]
        union = np.maximum(inside + seen - overlap, 1.0)
        corr = overlap / union
        a, b = np.unravel_index(int(np.argmax(corr)), corr.shape)
        # prefer the smallest shift among (numerically) equal maxima
        best = corr[a, b]
        ties = np.argwhere(corr >= best - 1e-9)
        if len(ties) > 1:
            d2 = (ties[:, 0] - self.pad) ** 2 + (ties[:, 1] - self.pad) ** 2
            a, b = ties[int(np.argmin(d2))]
        return int(self.pad - b), int(self.pad - a), float(best)


def _pool(a: np.ndarray, k: int) -> np.ndarray:
    """Boolean max-pooling over k x k blocks (the grid padded with False to a multiple of k)."""
    h, w = a.shape
    hp, wp = -(-h // k) * k, -(-w // k) * k
    b = np.zeros((hp, wp), dtype=bool)
    b[:h, :w] = a
    return b.reshape(hp // k, k, wp // k, k).any(axis=(1, 3))


def evaluate_map(map_grid, map_resolution_m: float, map_origin: Sequence[float],
                 truth_grid, truth_resolution_m: float, truth_origin: Sequence[float],
                 config: MapQualityConfig = MapQualityConfig()) -> MapQuality:
    """Align ``map_grid`` to ``truth_grid`` (both OccupancyGrid-valued, origins (x_m, y_m, yaw_rad) of
    cell (0, 0)'s corner in the same nominal frame) and score it; see the module docstring."""
    require_instance("config", config, MapQualityConfig)
    mg, mres, mo = _check_grid("map", map_grid, map_resolution_m, map_origin)
    tg, tres, to = _check_grid("truth", truth_grid, truth_resolution_m, truth_origin)
    if not (mg >= config.occupied_value).any():
        raise ValueError("the map has no occupied cells: nothing to align")
    if not (tg >= config.occupied_value).any():
        raise ValueError("the truth grid has no occupied cells")
    al = _Aligner(mg, mres, mo, tg, tres, to, config)

    def search(angles_deg):
        best = None
        for a in angles_deg:
            sx, sy, score = al.best_shift(math.radians(a))
            key = (score, -abs(a))
            if best is None or key > best[0]:
                best = (key, a, sx, sy)
        return best

    n = int(math.floor(config.max_rotation_deg / config.coarse_step_deg + 1e-9))
    coarse = search(config.coarse_step_deg * np.arange(-n, n + 1))
    a0 = coarse[1]
    k = int(math.ceil(config.coarse_step_deg / config.fine_step_deg))
    fine_angles = a0 + config.fine_step_deg * np.arange(-k, k + 1)
    fine = search(fine_angles[np.abs(fine_angles) <= config.max_rotation_deg + 1e-9])
    if fine[0] < coarse[0]:
        fine = coarse
    _, theta_deg, sx, sy = fine

    # scores at the best transform, on the (unpadded) truth grid
    rotated = al.rotated_map(math.radians(theta_deg))
    p = al.pad
    h, w = tg.shape
    shifted = rotated[p - sy:p - sy + h, p - sx:p - sx + w]          # M(q - t)
    observed = shifted >= 0
    m_occ = shifted >= config.occupied_value
    t_occ = al.truth_occ & observed
    cell = tres
    k = int(round(config.cell_m / tres)) if config.cell_m > 0 else 1
    if k > 1:
        m_occ, t_occ, observed = (_pool(a, k) for a in (m_occ, al.truth_occ, observed))
        t_occ &= observed
        cell = k * tres
    if config.tolerance_m > 0:
        r = config.tolerance_m / cell
        near_t = ndimage.distance_transform_edt(~t_occ) <= r
        near_m = ndimage.distance_transform_edt(~m_occ) <= r
        matched_m = int(np.count_nonzero(m_occ & near_t))
        matched_t = int(np.count_nonzero(t_occ & near_m))
        n_m, n_t = int(m_occ.sum()), int(t_occ.sum())
        iou = (matched_m + matched_t) / max(n_m + n_t, 1)
        precision = matched_m / max(n_m, 1)
        recall = matched_t / max(n_t, 1)
        matched = matched_m
    else:
        matched = int(np.count_nonzero(m_occ & t_occ))
        n_m, n_t = int(m_occ.sum()), int(t_occ.sum())
        union = int(np.count_nonzero(m_occ | t_occ))
        iou = matched / max(union, 1)
        precision = matched / max(n_m, 1)
        recall = matched / max(n_t, 1)
    tx, ty = sx * tres, sy * tres
    return MapQuality(float(iou), float(precision), float(recall), float(theta_deg), float(abs(theta_deg)),
                      float(tx), float(ty), float(math.hypot(tx, ty)), n_m, n_t, int(observed.sum()), matched)
