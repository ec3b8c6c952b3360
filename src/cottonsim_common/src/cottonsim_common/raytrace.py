"""The one Bresenham line tracer, compiled with numba, and the ray kernels built on it.

Why compiled: the obstacle layer clears every cell a sensor ray passes through
and SLAM adds log-odds along every beam, tens of thousands of rays per scan; a
Python loop over rays would take seconds. ``cache=True`` keeps the machine
code on disk between runs.

Cells are integer (column x, row y) indices of a grid ``grid[y, x]``.
:func:`trace_line` writes the cells from the start up to, but not including,
the end cell (that cell holds the obstacle, as in costmap_2d's raytraceLine);
callers decide what happens at the end.
"""
from __future__ import annotations

import numpy as np

try:
    from numba import njit
except ImportError as exc:  # pragma: no cover - numba is a declared dependency
    raise ImportError("cottonsim_common.raytrace needs numba (pip install numba)") from exc


@njit(cache=True, nogil=True)
def trace_line(x0, y0, x1, y1, out_x, out_y):
    """Bresenham cells from (x0, y0) towards (x1, y1), end cell excluded, into out_x / out_y.

    The buffers need max(|x1 - x0|, |y1 - y0|) entries. Returns the number of cells written.
    """
    dx = abs(x1 - x0)
    dy = abs(y1 - y0)
    sx = 1 if x1 > x0 else -1
    sy = 1 if y1 > y0 else -1
    err = dx - dy
    x = x0
    y = y0
    n = 0
    while not (x == x1 and y == y1):
        out_x[n] = x
        out_y[n] = y
        n += 1
        e2 = 2 * err
        if e2 > -dy:
            err -= dy
            x += sx
        if e2 < dx:
            err += dx
            y += sy
    return n


@njit(cache=True, nogil=True)
def longest_ray(x0, y0, x1, y1):
    """Buffer length :func:`trace_line` needs for every ray from (x0, y0) to (x1[i], y1[i])."""
    longest = 1
    for i in range(x1.shape[0]):
        longest = max(longest, abs(x1[i] - x0), abs(y1[i] - y0))
    return longest


@njit(cache=True, nogil=True)
def clear_rays(grid, x0, y0, x1, y1, value):
    """Set the cells of each ray from (x0, y0) to (x1[i], y1[i]) to ``value``.

    The end cell itself is left untouched; cells off the grid are skipped.
    Returns the number of cells written.
    """
    h, w = grid.shape
    n_max = longest_ray(x0, y0, x1, y1)
    cx = np.empty(n_max, dtype=np.int64)
    cy = np.empty(n_max, dtype=np.int64)
    written = 0
    for i in range(x1.shape[0]):
        n = trace_line(x0, y0, x1[i], y1[i], cx, cy)
        for k in range(n):
            if 0 <= cx[k] < w and 0 <= cy[k] < h:
                grid[cy[k], cx[k]] = value
                written += 1
    return written


def bresenham_cells(x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    """All cells (K, 2) of a Bresenham line, both ends included."""
    n_max = max(1, abs(x1 - x0), abs(y1 - y0))
    cx = np.empty(n_max, dtype=np.int64)
    cy = np.empty(n_max, dtype=np.int64)
    n = trace_line(np.int64(x0), np.int64(y0), np.int64(x1), np.int64(y1), cx, cy)
    cells = np.stack([cx[:n], cy[:n]], axis=1)
    return np.concatenate([cells, np.array([[x1, y1]], dtype=np.int64)])
