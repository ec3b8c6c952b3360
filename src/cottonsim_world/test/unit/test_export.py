"""Exports: occupancy map round trip, CSV / GPS route files, map loader errors."""
import csv
import json
import math
import os

import numpy as np
import pytest

from cottonsim_common.map_files import load_map_yaml, save_map
from cottonsim_common.pose import frame_to_world, world_to_frame
from cottonsim_world.farm.bolls import BollField
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.export import OccupancyMapConfig, export_all, rasterize_occupancy, write_bolls_csv
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.farm.model import Pose2D
from cottonsim_world.geodesy import HectorGeodesy


@pytest.fixture(scope="module")
def farm():
    return generate_farm(FarmConfig(rows=3, plants_per_row=5, plant_detail="low", plant_variants=2))


@pytest.fixture(scope="module")
def exported(farm, tmp_path_factory):
    out = tmp_path_factory.mktemp("farm")
    return export_all(farm, str(out))


def _cell(grid, res, origin, x, y):
    return grid[int((y - origin[1]) // res), int((x - origin[0]) // res)]


def test_map_round_trip_plants_occupied_lanes_free(farm, exported):
    grid, res, origin = load_map_yaml(exported["map_world"])
    assert res == pytest.approx(0.05) and origin[2] == 0.0
    assert set(np.unique(grid)) <= {0, 100}
    for p in farm.plants:
        assert _cell(grid, res, origin, p.x_m, p.y_m) == 100          # stems / canopy
        assert _cell(grid, res, origin, p.x_m + 0.1, p.y_m) == 100    # canopy at 0.3-0.5 m
    for lane in farm.lanes:
        for y in np.linspace(lane.y_start_m - 1, lane.y_end_m + 1, 30):
            assert _cell(grid, res, origin, lane.x_m, y) == 0
    for w in farm.route:
        assert _cell(grid, res, origin, w.x_m, w.y_m) == 0
    # occupied area ~ sum of the canopy discs at that height (order of magnitude)
    area = np.count_nonzero(grid == 100) * res * res
    assert 15 * math.pi * 0.1 ** 2 < area < 15 * math.pi * 0.35 ** 2
    # the in-memory raster equals what was loaded back
    g2, _, o2 = rasterize_occupancy(farm)
    np.testing.assert_array_equal(g2, grid)
    assert o2 == pytest.approx(origin)


def test_home_frame_map_matches_world_map(farm, exported):
    gw, res, ow = load_map_yaml(exported["map_world"])
    gh, _, oh = load_map_yaml(exported["map_home"])
    hx, hy = world_to_frame(farm.spawn, farm.plant_positions()[:, 0], farm.plant_positions()[:, 1])
    for x, y in zip(hx, hy):
        assert _cell(gh, res, oh, x, y) == 100
    # a lane point, transformed, is free in both maps
    lane = farm.lanes[1]
    lx, ly = world_to_frame(farm.spawn, lane.x_m, 0.5 * (lane.y_start_m + lane.y_end_m))
    assert _cell(gh, res, oh, float(lx), float(ly)) == 0
    assert abs(np.count_nonzero(gh == 100) - np.count_nonzero(gw == 100)) < 0.1 * np.count_nonzero(gw == 100)


def test_frames_round_trip_and_home_convention():
    spawn = Pose2D(-6.0, 1.0, math.pi / 2)
    x, y, yaw = world_to_frame(spawn, -1.43, 4.95, math.pi / 2)
    # Home frame: x_home = world_y - 1, y_home = -world_x - 6
    assert (float(x), float(y), float(yaw)) == pytest.approx((3.95, -4.57, 0.0))
    xw, yw, yaww = frame_to_world(spawn, x, y, yaw)
    assert (float(xw), float(yw), float(yaww)) == pytest.approx((-1.43, 4.95, math.pi / 2))


def test_pgm_header_and_values(exported):
    pgm = exported["map_world"].replace(".yaml", ".pgm")
    with open(pgm, "rb") as fh:
        data = fh.read()
    assert data.startswith(b"P5")
    assert set(np.frombuffer(data[-1000:], np.uint8)) <= {0, 254}
    import yaml
    meta = yaml.safe_load(open(exported["map_world"]))
    assert meta["negate"] == 0 and meta["occupied_thresh"] == 0.65 and meta["free_thresh"] == 0.196
    assert meta["image"] == "map_world.pgm"


def test_write_load_unknown_and_orientation(tmp_path):
    grid = np.full((4, 6), -1, np.int8)
    grid[0, 0] = 100         # bottom-left cell = origin
    grid[3, 5] = 0
    path = str(tmp_path / "m.yaml")
    save_map(path, grid, 0.1, (1.0, 2.0, 0.0))
    g, res, origin = load_map_yaml(path)
    np.testing.assert_array_equal(g, grid)
    assert res == pytest.approx(0.1) and origin == pytest.approx((1.0, 2.0, 0.0))
    # first image row = top of the map: the occupied pixel is in the last image row
    img = open(str(tmp_path / "m.pgm"), "rb").read()
    pixels = np.frombuffer(img[-24:], np.uint8).reshape(4, 6)
    assert pixels[3, 0] == 0 and pixels[0, 5] == 254 and pixels[1, 1] == 205


MAP_YAML = "image: t.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"


@pytest.mark.parametrize("yaml_text, pgm, error", [
    (None, None, "not found"),                                               # no YAML file
    ("image: t.pgm\nresolution: 0.05\n", None, "origin"),
    ("image: missing.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", None, "image file not found"),
    (MAP_YAML, b"P5\n10 10\n255\n" + bytes(20), "truncated"),
    (MAP_YAML, b"GIF89a", "not a PGM"),
    ("image: t.pgm\nresolution: -1\norigin: [0, 0, 0]\n", b"GIF89a", "resolution"),
    ("image: [unclosed\n", None, "YAML"),
])
def test_loader_errors(tmp_path, yaml_text, pgm, error):
    bad = tmp_path / "bad.yaml"
    if yaml_text is not None:
        bad.write_text(yaml_text)
    if pgm is not None:
        (tmp_path / "t.pgm").write_bytes(pgm)
    with pytest.raises(ValueError, match=error):
        load_map_yaml(str(bad))


def test_tables_and_route_files(farm, exported):
    rows = list(csv.DictReader(open(exported["plants"])))
    assert len(rows) == len(farm.plants)
    assert float(rows[0]["x_m"]) == pytest.approx(farm.plants[0].x_m, abs=1e-4)
    bolls = list(csv.DictReader(open(exported["bolls"])))
    assert len(bolls) == sum(len(p.model.boll_centres) for p in farm.plants)
    truth = BollField(farm)
    assert [int(r["boll_id"]) for r in bolls] == list(range(truth.count))
    assert {r["state"] for r in bolls} == {"ON_PLANT"}
    b7 = truth.get(7)
    assert (int(bolls[7]["plant_id"]), int(bolls[7]["boll"])) == (b7.plant_id, b7.index_on_plant)
    assert [float(bolls[7][k]) for k in ("x_m", "y_m", "z_m")] == pytest.approx(b7.position_m, abs=1e-4)
    assert float(bolls[7]["diameter_m"]) == pytest.approx(b7.diameter_m, abs=1e-4)
    lanes = list(csv.DictReader(open(exported["lanes"])))
    assert [float(r["x_m"]) for r in lanes] == pytest.approx([l.x_m for l in farm.lanes], abs=1e-4)
    world = list(csv.DictReader(open(exported["route_world"])))
    home = list(csv.DictReader(open(exported["route_home"])))
    assert [r["label"] for r in world] == farm.route_labels == [r["label"] for r in home]
    for w, h in zip(world, home):
        assert float(h["x_m"]) == pytest.approx(float(w["y_m"]) - 1.0, abs=2e-4)
        assert float(h["y_m"]) == pytest.approx(-float(w["x_m"]) - 6.0, abs=2e-4)
    ll = np.loadtxt(exported["route_gps"])
    x, y, _ = HectorGeodesy().geodetic_to_world(ll[:, 0], ll[:, 1])
    np.testing.assert_allclose(x, [w.x_m for w in farm.route], atol=1e-4)
    np.testing.assert_allclose(y, [w.y_m for w in farm.route], atol=1e-4)
    data = json.load(open(exported["farm_json"]))
    assert data["config"]["rows"] == 3 and len(data["plants"]) == len(farm.plants)
    assert len(data["route"]) == len(farm.route)
    assert [b["boll_id"] for b in data["bolls"]] == list(range(truth.count))
    assert data["bolls"][7]["plant_id"] == b7.plant_id and data["bolls"][7]["state"] == "ON_PLANT"


def test_bolls_csv_follows_the_field(farm, tmp_path):
    field = BollField(farm)
    field.detach(2, "nozzle", (1.0, 2.0, 3.0))
    field.drop_in_bin(5)
    write_bolls_csv(str(tmp_path / "bolls.csv"), farm, field)
    rows = list(csv.DictReader(open(tmp_path / "bolls.csv")))
    assert [r["state"] for r in rows[:6]] == ["ON_PLANT", "ON_PLANT", "HELD", "ON_PLANT", "ON_PLANT", "IN_BIN"]
    assert [float(rows[2][k]) for k in ("x_m", "y_m", "z_m")] == [1.0, 2.0, 3.0]


def test_map_config_validation():
    with pytest.raises(ValueError, match="resolution_m"):
        OccupancyMapConfig(resolution_m=0.0)
    with pytest.raises(ValueError, match="z_min_m"):
        OccupancyMapConfig(z_min_m=0.6, z_max_m=0.5)
