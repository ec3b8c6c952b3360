"""Synthetic maps shared by the localisation and mapping tests (a corridor and a two-row crop field)."""
import numpy as np

from cottonsim_navigation.core.grid import GridSpec, disc_occupancy


def corridor_map(res=0.05):
    """A 2 m wide corridor along +y (walls at |x| 1.0-1.2 m, y -1..15), an end wall and three boxes."""
    spec = GridSpec(res, int(10 / res), int(20 / res), -5.0, -2.0)
    occ = np.zeros(spec.shape, np.int8)
    gx, gy = spec.map_to_world(*np.meshgrid(np.arange(spec.width), np.arange(spec.height)))
    occ[(np.abs(gx) > 1.0) & (np.abs(gx) < 1.2) & (gy > -1) & (gy < 15)] = 100
    occ[(gy > -1.2) & (gy < -1.0) & (np.abs(gx) < 1.2)] = 100
    for bx, by in [(0.8, 3.0), (-0.8, 6.5), (0.75, 10.0)]:
        occ[(np.abs(gx - bx) < 0.2) & (np.abs(gy - by) < 0.4)] = 100
    return spec, occ


def field_map(res=0.05, n_rows=2):
    """Rows of 0.6 m plant discs every 0.7 m along +y (y 1.0..14.3), rows at x = -0.9 + 1.8 k."""
    spec = GridSpec(res, int(12 / res), int(24 / res), -6.0, -4.0)
    stems = [(-0.9 + 1.8 * r, 1.0 + 0.7 * i) for r in range(n_rows) for i in range(20)]
    return spec, disc_occupancy(spec, stems, 0.3)
