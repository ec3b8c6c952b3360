"""map_quality: hand-computed IoU / precision / recall, recovery of a known rigid error, pooling, tolerance,
bad input."""
import math

import numpy as np
import pytest

from cottonsim_navigation.evaluation.map_quality import MapQualityConfig, evaluate_map

RES = 0.05
EXACT = MapQualityConfig(max_rotation_deg=0.0, max_shift_m=0.0)


def plant_rows(res=RES, size_m=(12.0, 8.0)):
    """Truth: 4 rows of 0.25 m-radius plants along x (0.7 m pitch, 1.8 m apart), origin (0, 0)."""
    w, h = int(size_m[0] / res), int(size_m[1] / res)
    cx, cy = np.meshgrid((np.arange(w) + 0.5) * res, (np.arange(h) + 0.5) * res)
    g = np.zeros((h, w), np.int8)
    for row in range(4):
        for i in range(13):
            g[(cx - (1.5 + 0.7 * i)) ** 2 + (cy - (1.3 + 1.8 * row)) ** 2 <= 0.25 ** 2] = 100
    return g


def sample_truth(truth, theta_rad, t_xy, shape, map_origin):
    """A map whose cell p holds truth(R(theta) p + t): the truth seen through a rigid error (loop, nearest)."""
    h, w = shape
    out = np.full((h, w), -1, np.int8)
    c, s = math.cos(theta_rad), math.sin(theta_rad)
    for iy in range(h):
        for ix in range(w):
            px = map_origin[0] + (ix + 0.5) * RES
            py = map_origin[1] + (iy + 0.5) * RES
            qx, qy = c * px - s * py + t_xy[0], s * px + c * py + t_xy[1]
            jx, jy = int(math.floor(qx / RES)), int(math.floor(qy / RES))
            if 0 <= jx < truth.shape[1] and 0 <= jy < truth.shape[0]:
                out[iy, ix] = truth[jy, jx]
    return out


def test_hand_computed_scores_in_the_same_frame():
    truth = np.zeros((10, 10), np.int8)
    for iy, ix in ((2, 2), (2, 3), (2, 4), (5, 5)):
        truth[iy, ix] = 100
    m = np.zeros((10, 10), np.int8)
    for iy, ix in ((2, 2), (2, 3), (7, 7)):
        m[iy, ix] = 100
    q = evaluate_map(m, RES, (0, 0, 0), truth, RES, (0, 0, 0), EXACT)
    # M = {22, 23, 77}, T = {22, 23, 24, 55}: |M & T| = 2, |M | T| = 5
    assert q.iou == pytest.approx(2 / 5)
    assert q.precision == pytest.approx(2 / 3)
    assert q.recall == pytest.approx(2 / 4)
    assert (q.map_occupied_cells, q.truth_occupied_cells, q.matched_cells, q.observed_cells) == (3, 4, 2, 100)
    # a truth plant the map never observed does not count: T = {22, 23, 24}, union 4
    m[5, 5] = -1
    q = evaluate_map(m, RES, (0, 0, 0), truth, RES, (0, 0, 0), EXACT)
    assert q.iou == pytest.approx(2 / 4)
    assert q.recall == pytest.approx(2 / 3)
    assert q.observed_cells == 99


def test_identical_map_scores_one_without_correction():
    truth = plant_rows()
    q = evaluate_map(truth, RES, (0, 0, 0), truth, RES, (0, 0, 0), MapQualityConfig(max_rotation_deg=1.0))
    assert q.iou == pytest.approx(1.0)
    assert q.rotation_deg == 0.0 and q.shift_m == 0.0


def test_recovers_a_known_rotation_and_shift():
    truth = plant_rows()
    theta_deg, t = 0.8, (0.20, -0.15)
    origin = (-1.0, -1.0, 0.0)
    m = sample_truth(truth, math.radians(theta_deg), t, (200, 280), origin)
    # the exact frame gives a poor score, the search recovers the error: p_truth = R p_map + t
    q0 = evaluate_map(m, RES, origin, truth, RES, (0, 0, 0), EXACT)
    q = evaluate_map(m, RES, origin, truth, RES, (0, 0, 0), MapQualityConfig(max_rotation_deg=2.0))
    assert q0.iou < 0.5
    assert q.rotation_deg == pytest.approx(theta_deg, abs=0.05)
    assert q.shift_x_m == pytest.approx(t[0], abs=RES + 1e-9)
    assert q.shift_y_m == pytest.approx(t[1], abs=RES + 1e-9)
    assert q.iou > 0.85


def test_a_map_off_by_half_a_row_scores_low():
    """What slam.test's threshold must reject: a map built 0.9 m sideways (outside the search window)."""
    truth = plant_rows()
    m = sample_truth(truth, 0.0, (0.0, 0.9), truth.shape, (0.0, 0.0, 0.0))
    q = evaluate_map(m, RES, (0, 0, 0), truth, RES, (0, 0, 0),
                     MapQualityConfig(max_rotation_deg=1.0, max_shift_m=0.3, cell_m=0.25))
    assert abs(q.rotation_deg) <= 1.0
    assert q.iou < 0.25 and q.precision < 0.5      # slam.test needs IoU >= 0.25 and precision >= 0.8


def test_a_map_of_a_row_start_is_not_aligned_one_plant_spacing_on():
    """A correct map of the first 5 m of the rows (the rest unknown) with a few spurious hits 0.7 m before
    each row: moved one plant spacing (0.7 m) along the rows, every mapped plant still lands on a plant and
    the spurious hits land on each row's first plant, so the most-overlap alignment is off by a spacing
    (mapping_bringup.test once saw shift 0.65 m). The row's first plant then lies on ground the map saw
    free, which the IoU counts: the alignment stays in place."""
    truth = plant_rows()
    m = truth.copy()
    m[:, int(5.0 / RES):] = -1                       # the map has seen x < 5 m only
    for row in range(4):
        iy, ix = int((1.3 + 1.8 * row) / RES), int((1.5 - 0.7) / RES)
        m[iy - 1:iy + 2, ix - 1:ix + 2] = 100        # 9 spurious cells one spacing before the first plant
    q = evaluate_map(m, RES, (0, 0, 0), truth, RES, (0, 0, 0),
                     MapQualityConfig(max_rotation_deg=0.0, max_shift_m=1.0))
    assert q.shift_m == pytest.approx(0.0)
    assert q.precision > 0.95


def test_pooling_to_plant_scale_cells():
    truth = np.zeros((10, 10), np.int8)
    truth[0:2, 0:2] = 100                 # one 0.1 m block, fully occupied
    m = np.zeros((10, 10), np.int8)
    m[1, 1] = 100                         # one hit inside the same block
    exact = evaluate_map(m, RES, (0, 0, 0), truth, RES, (0, 0, 0), EXACT)
    assert exact.iou == pytest.approx(1 / 4)
    pooled = evaluate_map(m, RES, (0, 0, 0), truth, RES, (0, 0, 0),
                          MapQualityConfig(max_rotation_deg=0.0, max_shift_m=0.0, cell_m=0.1))
    assert pooled.iou == pytest.approx(1.0)
    assert pooled.observed_cells == 25   # 10 x 10 cells in 2 x 2 blocks


def test_tolerance_matches_neighbouring_cells():
    truth = np.zeros((10, 10), np.int8)
    truth[4, 4] = 100
    m = np.zeros((10, 10), np.int8)
    m[4, 5] = 100                         # one cell (0.05 m) off
    q0 = evaluate_map(m, RES, (0, 0, 0), truth, RES, (0, 0, 0), EXACT)
    assert q0.iou == 0.0
    q = evaluate_map(m, RES, (0, 0, 0), truth, RES, (0, 0, 0),
                     MapQualityConfig(max_rotation_deg=0.0, max_shift_m=0.0, tolerance_m=0.06))
    assert q.iou == pytest.approx(1.0)
    q = evaluate_map(m, RES, (0, 0, 0), truth, RES, (0, 0, 0),
                     MapQualityConfig(max_rotation_deg=0.0, max_shift_m=0.0, tolerance_m=0.04))
    assert q.iou == 0.0


@pytest.mark.parametrize("kwargs, name", [
    ({"max_rotation_deg": -1.0}, "max_rotation_deg"), ({"coarse_step_deg": 0.0}, "coarse_step_deg"),
    ({"fine_step_deg": 1.0}, "fine_step_deg"), ({"max_shift_m": float("nan")}, "max_shift_m"),
    ({"occupied_value": 0}, "occupied_value"), ({"tolerance_m": -0.1}, "tolerance_m"),
    ({"cell_m": float("inf")}, "cell_m")])
def test_bad_config_names_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        MapQualityConfig(**kwargs)


def test_bad_grids_raise_clear_errors():
    truth = plant_rows()
    with pytest.raises(ValueError, match="no occupied"):
        evaluate_map(np.zeros((5, 5), np.int8), RES, (0, 0, 0), truth, RES, (0, 0, 0))
    with pytest.raises(ValueError, match="origin"):
        evaluate_map(truth, RES, (0, float("nan"), 0), truth, RES, (0, 0, 0))
    with pytest.raises(ValueError, match="resolution_m"):
        evaluate_map(truth, 0.0, (0, 0, 0), truth, RES, (0, 0, 0))
    with pytest.raises(ValueError, match="2-D"):
        evaluate_map(np.zeros(5, np.int8), RES, (0, 0, 0), truth, RES, (0, 0, 0))
    with pytest.raises(ValueError, match="integers"):
        evaluate_map(truth.astype(float), RES, (0, 0, 0), truth, RES, (0, 0, 0))


def test_map_on_truth_cells_shows_the_map_as_registered():
    """Same cells -> the same values; a map whose origin is 2 cells further along x shows its content
    2 truth cells further along x (no alignment); cells the map does not cover read -1."""
    from cottonsim_navigation.evaluation.map_quality import map_on_truth_cells
    grid = np.zeros((4, 6), dtype=np.int16)
    grid[1, 2] = 100
    same = map_on_truth_cells(grid, 0.05, (0.0, 0.0, 0.0), grid.shape, 0.05, (0.0, 0.0, 0.0))
    np.testing.assert_array_equal(same, grid)
    moved = map_on_truth_cells(grid, 0.05, (0.10, 0.0, 0.0), grid.shape, 0.05, (0.0, 0.0, 0.0))
    assert moved[1, 4] == 100 and moved[1, 2] == 0
    assert (moved[:, :2] == -1).all()
    with pytest.raises(ValueError, match="truth_shape"):
        map_on_truth_cells(grid, 0.05, (0.0, 0.0, 0.0), (0, 3), 0.05, (0.0, 0.0, 0.0))
