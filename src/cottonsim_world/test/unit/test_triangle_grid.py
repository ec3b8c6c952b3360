"""The LiDAR's triangle grid lists each triangle in exactly the cells it meets (up to a thin margin).

The grid is what makes the numba ray caster exact: a hit at distance t lies
in some cell the ray walks through, and that cell must list the triangle.
Cells are checked against points sampled on the triangles (independent of
the separating-axis test the grid uses) and against the triangles' bounding
boxes, which the grid must not fill blindly.
"""
import numpy as np

from cottonsim_world.sensors.fast.geometry import BRICK, TriangleGrid


def listed_cells(grid, index):
    """Set of (ix, iy, iz) cells whose list holds sorted triangle ``index``."""
    out = set()
    nbx, nby, nbz = grid.bdims
    for coarse in np.nonzero(grid.brick_of >= 0)[0]:
        bx, by, bz = coarse % nbx, (coarse // nbx) % nby, coarse // (nbx * nby)
        b = grid.brick_of[coarse]
        for local in range(BRICK ** 3):
            c = b * BRICK ** 3 + local
            if index in grid.items[grid.offsets[c]:grid.offsets[c + 1]]:
                lx, ly, lz = local % BRICK, (local // BRICK) % BRICK, local // (BRICK * BRICK)
                out.add((bx * BRICK + lx, by * BRICK + ly, bz * BRICK + lz))
    return out


def test_every_cell_a_triangle_meets_lists_it_and_far_box_corners_do_not():
    rng = np.random.default_rng(3)
    # long thin diagonal slivers (their boxes hold many cells they do not meet) and small random triangles
    base = rng.uniform(0.0, 0.5, size=(6, 3))
    slivers = np.stack([base, base + [0.4, 0.4, 0.4], base + [0.41, 0.39, 0.4]], axis=1)
    small = rng.uniform(0.0, 0.6, size=(20, 1, 3)) + rng.normal(0.0, 0.04, size=(20, 3, 3))
    tris = np.concatenate([slivers, small])
    grid = TriangleGrid(tris, np.arange(len(tris), dtype=np.int32), cell_m=0.05)
    sorted_tris = tris[grid.tri_id]
    for index in range(len(tris)):
        cells = listed_cells(grid, index)
        t = sorted_tris[index]
        w = rng.dirichlet(np.ones(3), size=400)
        pts = w @ t
        want = {tuple(c) for c in np.floor((pts - grid.lo) / grid.cell_m).astype(int)}
        assert want <= cells, f"triangle {index}: cells it meets are not listed: {sorted(want - cells)[:5]}"
        lo = np.floor((t.min(axis=0) - grid.lo) / grid.cell_m).astype(int)
        hi = np.floor((t.max(axis=0) - grid.lo) / grid.cell_m).astype(int)
        box = int(np.prod(hi - lo + 1))
        assert len(cells) <= box
        if grid.tri_id[index] < len(slivers):
            # a sliver along the box diagonal meets a small part of its 9 x 9 x 9 box
            assert len(cells) < 0.4 * box, (len(cells), box)
            # ... and not the box corner farthest from its cells
            corner = (lo[0], hi[1], hi[2]) if t[0, 0] < t[1, 0] else (hi[0], lo[1], lo[2])
            assert corner not in cells
