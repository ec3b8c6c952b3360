"""crop_to_known: hand-computed crops, margins clipped at the border, yawed origins, bad input."""
import math

import numpy as np
import pytest

from cottonsim_navigation.mapping.map_crop import crop_to_known


def test_crop_with_margin_hand_computed():
    g = np.full((20, 30), -1, np.int8)
    g[5:8, 10:14] = 0
    g[6, 12] = 100
    out, origin = crop_to_known(g, 0.1, (-1.0, 2.0, 0.0), margin_m=0.2)
    # known rows 5..7, cols 10..13; margin 2 cells -> rows 3..9, cols 8..15
    assert out.shape == (7, 8)
    assert origin == pytest.approx((-1.0 + 0.8, 2.0 + 0.3, 0.0))
    assert out[3, 4] == 100 and (out == 0).sum() == 11 and (out == -1).sum() == 56 - 12


def test_margin_is_clipped_at_the_grid_border():
    g = np.full((4, 4), -1, np.int8)
    g[0, 3] = 0
    out, origin = crop_to_known(g, 0.5, (0, 0, 0), margin_m=10.0)
    assert out.shape == (4, 4) and origin == pytest.approx((0, 0, 0))


def test_yawed_origin_moves_along_the_grid_axes():
    g = np.full((10, 10), -1, np.int8)
    g[4, 2] = 0
    _, origin = crop_to_known(g, 1.0, (1.0, 1.0, math.pi / 2), margin_m=0.0)
    # cell (ix 2, iy 4) corner in the grid axes (2, 4) -> rotated by 90 deg: (-4, 2)
    assert origin == pytest.approx((1.0 - 4.0, 1.0 + 2.0, math.pi / 2))


def test_bad_input():
    with pytest.raises(ValueError, match="no known"):
        crop_to_known(np.full((3, 3), -1, np.int8), 0.05, (0, 0, 0))
    with pytest.raises(ValueError, match="margin_m"):
        crop_to_known(np.zeros((3, 3), np.int8), 0.05, (0, 0, 0), margin_m=-1)
    with pytest.raises(ValueError, match="resolution_m"):
        crop_to_known(np.zeros((3, 3), np.int8), float("nan"), (0, 0, 0))
    with pytest.raises(ValueError, match="origin"):
        crop_to_known(np.zeros((3, 3), np.int8), 0.05, (0, 0))
