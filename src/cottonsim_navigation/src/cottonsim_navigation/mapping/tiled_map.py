"""A particle's occupancy map in log-odds, stored as copy-on-write tiles, and the ray update into it.

Maps are stored in 64 x 64-cell int16 tiles (log-odds x ``LOGODDS_SCALE``)
that exist only where something was observed; resampled copies share tiles
and copy one only when they write into it. ``integrate_beams`` adds a scan's
beams (Bresenham rays: a miss on each cell crossed, a hit or miss on the end
cell) to a dense window read from the tiles.
"""
from __future__ import annotations

from typing import Dict, Optional, Tuple

import numpy as np

from cottonsim_common.raytrace import longest_ray, trace_line

from ..core.grid import GridSpec

try:
    from numba import njit
except ImportError as exc:  # pragma: no cover - numba is a declared dependency
    raise ImportError("cottonsim_navigation needs numba (pip install numba) for SLAM") from exc

TILE = 64                 # cells per tile edge
LOGODDS_SCALE = 100.0     # int16 map value = log-odds * LOGODDS_SCALE


class TiledLogOddsMap:
    """A log-odds grid stored as copy-on-write tiles (int16, log-odds x LOGODDS_SCALE; absent = 0 = unknown)."""

    def __init__(self, spec: GridSpec, tiles: Optional[Dict[Tuple[int, int], np.ndarray]] = None) -> None:
        self.spec = spec
        self.tiles: Dict[Tuple[int, int], np.ndarray] = {} if tiles is None else tiles

    def clone(self) -> "TiledLogOddsMap":
        """A copy sharing every tile array. Tile arrays are never changed in place (write() stores
        new arrays), so sharing is safe: this is copy-on-write at tile granularity."""
        return TiledLogOddsMap(self.spec, dict(self.tiles))

    def tile_range(self, mx0: int, my0: int, mx1: int, my1: int) -> Tuple[int, int, int, int]:
        """Tiles (tx0, ty0, tx1, ty1), inclusive, covering cells [mx0, mx1] x [my0, my1] clipped to the grid."""
        nx = (self.spec.width + TILE - 1) // TILE
        ny = (self.spec.height + TILE - 1) // TILE
        tx0 = min(max(mx0 // TILE, 0), nx - 1)
        ty0 = min(max(my0 // TILE, 0), ny - 1)
        tx1 = min(max(mx1 // TILE, 0), nx - 1)
        ty1 = min(max(my1 // TILE, 0), ny - 1)
        return tx0, ty0, tx1, ty1

    def read(self, tr: Tuple[int, int, int, int]) -> np.ndarray:
        """Dense copy of the tiles in range ``tr`` (cell (0, 0) = first cell of tile (tx0, ty0))."""
        tx0, ty0, tx1, ty1 = tr
        out = np.zeros(((ty1 - ty0 + 1) * TILE, (tx1 - tx0 + 1) * TILE), dtype=np.int16)
        for (ty, tx), tile in self.tiles.items():
            if tx0 <= tx <= tx1 and ty0 <= ty <= ty1:
                out[(ty - ty0) * TILE:(ty - ty0 + 1) * TILE, (tx - tx0) * TILE:(tx - tx0 + 1) * TILE] = tile
        return out

    def write(self, tr: Tuple[int, int, int, int], dense: np.ndarray, touched: np.ndarray) -> None:
        """Store fresh copies of the tiles of ``dense`` flagged in ``touched`` [(ty1-ty0+1), (tx1-tx0+1)]."""
        tx0, ty0, _, _ = tr
        for iy, ix in zip(*np.nonzero(touched)):
            key = (ty0 + int(iy), tx0 + int(ix))
            self.tiles[key] = dense[iy * TILE:(iy + 1) * TILE, ix * TILE:(ix + 1) * TILE].copy()

    def window_spec(self, tr: Tuple[int, int, int, int]) -> GridSpec:
        tx0, ty0, tx1, ty1 = tr
        r = self.spec.resolution_m
        return GridSpec(r, (tx1 - tx0 + 1) * TILE, (ty1 - ty0 + 1) * TILE,
                        self.spec.origin_x_m + tx0 * TILE * r, self.spec.origin_y_m + ty0 * TILE * r)

    def nbytes(self) -> int:
        return sum(t.nbytes for t in self.tiles.values())


@njit(cache=True, nogil=True)
def integrate_beams(grid, touched, x0, y0, ex, ey, hit, add_miss, add_hit, clamp):
    """Ray-trace beams from cell (x0, y0) to (ex[i], ey[i]) adding log-odds; marks touched tiles."""
    h, w = grid.shape
    n_max = longest_ray(x0, y0, ex, ey)
    cx = np.empty(n_max, dtype=np.int64)
    cy = np.empty(n_max, dtype=np.int64)
    for i in range(ex.shape[0]):
        bx = ex[i]
        by = ey[i]
        n = trace_line(x0, y0, bx, by, cx, cy)
        for k in range(n):
            x = cx[k]
            y = cy[k]
            if 0 <= x < w and 0 <= y < h:
                v = grid[y, x] + add_miss
                grid[y, x] = v if v > -clamp else -clamp
                touched[y // TILE, x // TILE] = True
        if 0 <= bx < w and 0 <= by < h:
            if hit[i]:
                v = grid[by, bx] + add_hit
                grid[by, bx] = v if v < clamp else clamp
            else:
                v = grid[by, bx] + add_miss
                grid[by, bx] = v if v > -clamp else -clamp
            touched[by // TILE, bx // TILE] = True
