"""Compiled grid kernels (numba): Bresenham ray clearing.

The obstacle layer clears every cell a sensor ray passes through, for tens of
thousands of rays per scan; a Python loop over rays would take seconds, so the
loop is compiled with numba (``cache=True`` keeps the machine code on disk
between runs).
"""
from __future__ import annotations

import numpy as np

try:
    from numba import njit
except ImportError as exc:  # pragma: no cover - numba is a declared dependency
    raise ImportError("cottonsim_navigation needs numba (pip install numba) for its grid kernels") from exc


@njit(cache=True, nogil=True)
def clear_rays(grid, x0, y0, x1, y1, value):
    """Set the cells of each ray from (x0, y0) to (x1[i], y1[i]) to ``value``.

    Cell indices are integers (column, row); the end cell itself is left
    untouched (it holds the obstacle), like costmap_2d's raytraceLine. Cells
    off the grid are skipped. Returns the number of cells written.
    """
    h, w = grid.shape
    written = 0
    for i in range(x1.shape[0]):
        ax = x0
        ay = y0
        bx = x1[i]
        by = y1[i]
        dx = abs(bx - ax)
        dy = abs(by - ay)
        sx = 1 if bx > ax else -1
        sy = 1 if by > ay else -1
        err = dx - dy
        x = ax
        y = ay
        while not (x == bx and y == by):
            if 0 <= x < w and 0 <= y < h:
                grid[y, x] = value
                written += 1
            e2 = 2 * err
            if e2 > -dy:
                err -= dy
                x += sx
            if e2 < dx:
                err += dx
                y += sy
    return written


def bresenham_cells(x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    """All cells (K, 2) of a Bresenham line, both ends included (pure Python, for tests and small jobs)."""
    cells = []
    dx, dy = abs(x1 - x0), abs(y1 - y0)
    sx = 1 if x1 > x0 else -1
    sy = 1 if y1 > y0 else -1
    err = dx - dy
    x, y = x0, y0
    while True:
        cells.append((x, y))
        if x == x1 and y == y1:
            break
        e2 = 2 * err
        if e2 > -dy:
            err -= dy
            x += sx
        if e2 < dx:
            err += dx
            y += sy
    return np.array(cells, dtype=np.int64)
