"""core.grid.disc_occupancy: plant stems as occupied discs on a grid."""
import numpy as np

from cottonsim_navigation.core.grid import GridSpec, disc_occupancy


def test_cells_within_the_radius_of_a_centre_are_occupied_and_the_rest_free():
    spec = GridSpec(0.1, 20, 10, -1.0, 0.0)                   # cell centres at x -0.95..0.95, y 0.05..0.95
    occ = disc_occupancy(spec, [(0.0, 0.5), (0.75, 0.25)], 0.2)
    assert occ.dtype == np.int8 and occ.shape == spec.shape
    gx, gy = spec.map_to_world(*np.meshgrid(np.arange(spec.width), np.arange(spec.height)))
    near = np.minimum(np.hypot(gx - 0.0, gy - 0.5), np.hypot(gx - 0.75, gy - 0.25)) <= 0.2
    assert np.array_equal(occ == 100, near) and set(np.unique(occ)) == {0, 100}
    assert not disc_occupancy(spec, [], 0.2).any()
