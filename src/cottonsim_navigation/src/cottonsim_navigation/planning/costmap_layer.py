"""The base class of costmap layers and the helpers the layers share."""
from __future__ import annotations

import abc

import numpy as np

from cottonsim_common.pose import Pose2D


def shift_grid(grid: np.ndarray, dx: int, dy: int, fill: int) -> np.ndarray:
    """Content moved so that new[y, x] = old[y + dy, x + dx]; uncovered cells = fill."""
    out = np.full_like(grid, fill)
    h, w = grid.shape
    if abs(dx) >= w or abs(dy) >= h:
        return out
    sx0, sx1 = max(0, dx), min(w, w + dx)
    sy0, sy1 = max(0, dy), min(h, h + dy)
    out[sy0 - dy:sy1 - dy, sx0 - dx:sx1 - dx] = grid[sy0:sy1, sx0:sx1]
    return out



class CostmapLayer(abc.ABC):
    """One layer of a :class:`Costmap2D` (a costmap_2d plugin)."""

    name: str = "layer"
    enabled: bool = True

    def match_size(self, costmap: "Costmap2D") -> None:
        """The master grid was (re)created: allocate layer storage. Default: nothing."""

    def shift(self, costmap: "Costmap2D", dx_cells: int, dy_cells: int) -> None:
        """The rolling window moved by (dx, dy) cells: keep what stays in view. Default: nothing."""

    @abc.abstractmethod
    def update_costs(self, master: np.ndarray, costmap, robot_pose: Pose2D) -> None:
        """Write this layer's contribution into ``master`` (uint8, in place).

        ``costmap`` is the :class:`Costmap2D` or, for a window update, a view of
        it: ``master`` then covers only ``costmap.spec`` (the window's cells),
        which are ``costmap.window`` (row and column slices) of the full grid
        ``costmap.full_spec``.
        """
