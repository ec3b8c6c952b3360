"""Farm generator: layout geometry, randomness, route, fit to the original."""
import math
import pathlib

import numpy as np
import pytest

from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.geodesy import HectorGeodesy

# the original CottonSim GPS route, committed with the navigation package
WAYPOINTS = str(pathlib.Path(__file__).resolve().parents[3] / "cottonsim_navigation" / "config" / "waypoints"
                / "original_gps_waypoints.txt")
SMALL = dict(rows=3, plants_per_row=6, plant_detail="low", plant_variants=3)


@pytest.fixture(scope="module")
def default_farm():
    return generate_farm(FarmConfig(plant_detail="low"))


def test_counts_ids_and_spacings(default_farm):
    farm, c = default_farm, default_farm.config
    assert len(farm.plants) == 180 and len(farm.lanes) == 10
    assert [p.plant_id for p in farm.plants] == list(range(180))
    xy = farm.plant_positions()
    for row in range(9):
        sel = np.array([p.row == row for p in farm.plants])
        # one x per row, rows 1.8 m apart from east to west
        assert np.allclose(xy[sel, 0], -1.43 - 1.8 * (row + 0.5))
        ys = np.sort(xy[sel, 1])
        assert np.allclose(np.diff(ys), 0.7)
        assert ys[0] == pytest.approx(8.95) and ys[-1] == pytest.approx(22.25)
    idx = [p.index_in_row for p in farm.plants if p.row == 0]
    assert idx == list(range(20))


def test_lane_centres_midway_between_rows(default_farm):
    farm = default_farm
    row_x = sorted({round(p.x_m, 6) for p in farm.plants}, reverse=True)
    lanes = [l.x_m for l in farm.lanes]
    assert lanes == sorted(lanes, reverse=True)                     # east to west
    for k in range(1, 9):
        assert lanes[k] == pytest.approx(0.5 * (row_x[k - 1] + row_x[k]))
    assert lanes[0] - row_x[0] == pytest.approx(0.9)                # outer lanes
    assert row_x[-1] - lanes[-1] == pytest.approx(0.9)
    for lane in farm.lanes:
        assert lane.y_start_m == pytest.approx(8.95 - 0.35) and lane.y_end_m == pytest.approx(22.25 + 0.35)


def test_default_lanes_fit_original_waypoints():
    ll = np.loadtxt(WAYPOINTS)
    x, y, _ = HectorGeodesy().geodetic_to_world(ll[:, 0], ll[:, 1])
    lane_x = x.reshape(10, 3).mean(axis=1)
    k = np.arange(10)
    c = FarmConfig()
    # least squares of lane_x ~ x0 - spacing * k with the paper's spacing
    x0 = float(np.mean(lane_x + c.row_spacing_m * k))
    assert x0 == pytest.approx(-1.43, abs=0.03)
    assert c.first_lane_x_m == pytest.approx(x0, abs=0.02)
    # every original waypoint lies in a lane, >= 0.2 m from any canopy edge
    row_x = np.array([c.row_x_m(r) for r in range(c.rows)])
    edge_gap = np.abs(x[:, None] - row_x[None, :]).min(axis=1) - c.plant_width_m / 2
    assert edge_gap.min() >= 0.2
    # the middle waypoints sit at the middle of the rows
    mid = y.reshape(10, 3)[:, 1].mean()
    assert 0.5 * (c.first_plant_y_m + c.last_plant_y_m) == pytest.approx(mid, abs=0.3)


def test_route_is_serpentine(default_farm):
    farm, c = default_farm, default_farm.config
    assert len(farm.route) == 30 and len(farm.route_labels) == 30
    assert farm.route_labels[:4] == ["1-1", "1-2", "1-3", "O2-1"] and farm.route_labels[-1] == "O10-3"
    for k in range(10):
        wps = farm.route[3 * k:3 * k + 3]
        assert all(w.x_m == pytest.approx(farm.lanes[k].x_m) for w in wps)
        ys = [w.y_m for w in wps]
        north = k % 2 == 0
        assert (ys == sorted(ys)) if north else (ys == sorted(ys, reverse=True))
        assert all(w.yaw_rad == pytest.approx(math.pi / 2 if north else -math.pi / 2) for w in wps)
        assert min(ys) < c.first_plant_y_m - c.plant_width_m and max(ys) > c.last_plant_y_m + c.plant_width_m
    assert (farm.spawn.x_m, farm.spawn.y_m) == (-6.0, 1.0)


def test_same_config_same_farm_and_seeds_differ_with_jitter():
    cfg = FarmConfig(position_jitter_m=0.05, height_jitter_fraction=0.1, **SMALL)
    a, b = generate_farm(cfg), generate_farm(cfg)
    np.testing.assert_array_equal(a.plant_positions(), b.plant_positions())
    assert [p.yaw_rad for p in a.plants] == [p.yaw_rad for p in b.plants]
    for pa, pb in zip(a.plants, b.plants):
        np.testing.assert_array_equal(pa.boll_centres_world(), pb.boll_centres_world())
    c = generate_farm(FarmConfig(position_jitter_m=0.05, height_jitter_fraction=0.1, seed=1, **SMALL))
    assert not np.allclose(a.plant_positions(), c.plant_positions())
    # jitter bounded, heights vary within the fraction
    nominal = generate_farm(FarmConfig(**SMALL)).plant_positions()
    d = np.abs(a.plant_positions() - nominal)
    assert d.max() <= 0.05 + 1e-12 and d.max() > 0.01
    heights = {round(p.model.height_m, 6) for p in a.plants}
    assert len(heights) > 1 and all(0.9 - 1e-9 <= h <= 1.1 + 1e-9 for h in heights)


def test_missing_plants():
    farm = generate_farm(FarmConfig(rows=4, plants_per_row=25, missing_plant_fraction=0.3,
                                    plant_detail="low", plant_variants=2, seed=2))
    n = len(farm.plants)
    assert 40 < n < 90                                  # ~70 of 100 expected
    ids = [p.plant_id for p in farm.plants]
    assert len(set(ids)) == n and all(pid == p.row * 25 + p.index_in_row for pid, p in zip(ids, farm.plants))
    assert len(farm.lanes) == 5 and len(farm.route) == 15


def test_bolls_inside_the_canopy_and_in_range():
    cfg = FarmConfig(bolls_per_plant=(5, 9), **SMALL)
    farm = generate_farm(cfg)
    counts = set()
    for p in farm.plants:
        b = p.boll_centres_world()
        counts.add(len(b))
        assert 5 <= len(b) <= 9
        assert np.all(np.hypot(b[:, 0] - p.x_m, b[:, 1] - p.y_m) <= cfg.plant_width_m / 2)
        assert np.all((b[:, 2] > 0) & (b[:, 2] <= p.model.height_m))
    assert len(counts) > 1


def test_variants_are_shared_and_zero_means_unique():
    farm = generate_farm(FarmConfig(**SMALL))
    assert len({id(p.model) for p in farm.plants}) <= 3
    farm = generate_farm(FarmConfig(rows=2, plants_per_row=3, plant_detail="low", plant_variants=0))
    assert len({id(p.model) for p in farm.plants}) == 6


def test_bad_config_type():
    with pytest.raises(ValueError, match="FarmConfig"):
        generate_farm({"rows": 3})
