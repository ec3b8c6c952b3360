"""The one Bresenham tracer and the ray kernels built on it."""
import numpy as np

from cottonsim_common.raytrace import bresenham_cells, clear_rays, longest_ray, trace_line


def test_bresenham_known_lines_both_ends_included():
    assert bresenham_cells(0, 0, 4, 2).tolist() == [[0, 0], [1, 0], [2, 1], [3, 1], [4, 2]]
    assert bresenham_cells(3, 3, 3, 3).tolist() == [[3, 3]]
    assert bresenham_cells(2, 0, -1, 0).tolist() == [[2, 0], [1, 0], [0, 0], [-1, 0]]


def test_trace_line_leaves_out_the_end_cell():
    cx, cy = np.zeros(5, np.int64), np.zeros(5, np.int64)
    n = trace_line(np.int64(0), np.int64(0), np.int64(0), np.int64(-3), cx, cy)
    assert n == 3 and cx[:n].tolist() == [0, 0, 0] and cy[:n].tolist() == [0, -1, -2]
    assert longest_ray(np.int64(1), np.int64(1), np.array([4, 1], np.int64), np.array([1, -6], np.int64)) == 7


def test_clear_rays_skips_off_grid_cells_and_the_obstacle():
    grid = np.full((4, 6), 100, dtype=np.int8)
    written = clear_rays(grid, np.int64(0), np.int64(0), np.array([5, 0, -3], np.int64),
                         np.array([0, 3, 0], np.int64), 0)
    assert grid[0, 5] == 100 and grid[3, 0] == 100              # end cells keep their obstacle
    assert (grid[0, :5] == 0).all() and (grid[:3, 0] == 0).all()
    assert written == 5 + 3 + 1                                 # the third ray leaves the grid after its start
