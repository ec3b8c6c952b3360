"""Empty map and map_saver export; the saved files read back with the project's map loader."""
import numpy as np
import pytest

from cottonsim_common.map_files import (PGM_FREE, PGM_OCCUPIED, PGM_UNKNOWN, EmptyMapConfig, MapSaverConfig,
                                        empty_map, load_map_yaml, occupancy_to_pgm, save_map)


def test_empty_map_size_and_content():
    grid, res, origin = empty_map(EmptyMapConfig(width_m=3.0, height_m=2.0, resolution=0.1, origin=(-1, -2, 0)))
    assert grid.shape == (20, 30) and grid.dtype == np.int8 and not grid.any()
    assert res == 0.1 and origin == (-1.0, -2.0, 0.0)
    default, _, _ = empty_map()
    assert default.shape == (2000, 2000)


@pytest.mark.parametrize("kwargs, named", [
    ({"width_m": 0.0}, "width_m"), ({"height_m": float("nan")}, "height_m"), ({"resolution": -0.05}, "resolution"),
    ({"origin": (0.0, 0.0)}, "origin"), ({"origin": (0.0, float("inf"), 0.0)}, "origin"),
    ({"width_m": 1e5, "resolution": 0.001}, "cells"),
])
def test_empty_map_config_is_validated(kwargs, named):
    with pytest.raises(ValueError, match=named):
        EmptyMapConfig(**kwargs)


def test_trinary_thresholds_like_map_saver():
    # one row (y = 0 is the bottom) of values across the thresholds
    row = np.array([[-1, 0, 19, 20, 50, 64, 65, 100]], dtype=np.int8)
    img = occupancy_to_pgm(row)
    expected = [PGM_UNKNOWN, PGM_FREE, PGM_FREE, PGM_UNKNOWN, PGM_UNKNOWN, PGM_UNKNOWN, PGM_OCCUPIED, PGM_OCCUPIED]
    assert img.tolist() == [expected]
    # the image's first row is the top of the map (largest y)
    grid = np.array([[100, 100], [0, 0]], dtype=np.int8)
    assert occupancy_to_pgm(grid).tolist() == [[PGM_FREE, PGM_FREE], [PGM_OCCUPIED, PGM_OCCUPIED]]
    # custom thresholds
    img = occupancy_to_pgm(row, MapSaverConfig(occupied_thresh=50, free_thresh=25))
    assert img[0, 3] == PGM_FREE and img[0, 4] == PGM_OCCUPIED


def test_saver_config_and_bad_grids():
    with pytest.raises(ValueError, match="free_thresh"):
        MapSaverConfig(occupied_thresh=20, free_thresh=30)
    with pytest.raises(ValueError, match="occupied_thresh"):
        MapSaverConfig(occupied_thresh=150)
    with pytest.raises(ValueError, match="2-D"):
        occupancy_to_pgm(np.zeros(5, dtype=np.int8))
    with pytest.raises(ValueError, match="integers"):
        occupancy_to_pgm(np.zeros((2, 2)))


def test_save_then_load_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    grid = rng.choice(np.array([-1, 0, 100], dtype=np.int8), size=(37, 53))
    pgm, yaml_path = save_map(str(tmp_path / "farm"), grid, 0.05, (-100.0, -100.0, 0.0))
    assert pgm.endswith("farm.pgm") and yaml_path.endswith("farm.yaml")
    back, res, origin = load_map_yaml(yaml_path)
    assert back.shape == grid.shape and np.array_equal(back, grid)
    assert res == pytest.approx(0.05) and origin == pytest.approx((-100.0, -100.0, 0.0))
    text = open(yaml_path).read()
    assert "image: farm.pgm" in text and "occupied_thresh: 0.65" in text and "free_thresh: 0.196" in text
    # intermediate values are written as unknown grey
    mid = np.full((2, 2), 40, dtype=np.int8)
    _, yaml2 = save_map(str(tmp_path / "mid.yaml"), mid, 0.1, (0, 0, 0))
    assert (load_map_yaml(yaml2)[0] == -1).all()


def test_save_map_refuses_bad_input(tmp_path):
    grid = np.zeros((2, 2), dtype=np.int8)
    with pytest.raises(ValueError, match="does not exist"):
        save_map(str(tmp_path / "nope" / "map"), grid, 0.05, (0, 0, 0))
    with pytest.raises(ValueError, match="resolution_m"):
        save_map(str(tmp_path / "map"), grid, 0.0, (0, 0, 0))
    with pytest.raises(ValueError, match="origin"):
        save_map(str(tmp_path / "map"), grid, 0.05, (0, 0))
