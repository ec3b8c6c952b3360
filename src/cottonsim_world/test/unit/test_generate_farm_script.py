"""scripts/generate_farm: --geodesy-reference puts the GPS exports at another farm's reference."""
import csv
import pathlib

import numpy as np

from cottonsim_common.testing import load_script
from cottonsim_world.geodesy import HectorGeodesy

PKG = pathlib.Path(__file__).resolve().parents[2]


def _route(out):
    with open(out / "route_world.csv") as fh:
        world = np.array([[float(r["x_m"]), float(r["y_m"])] for r in csv.DictReader(fh)])
    return world, np.loadtxt(out / "route_gps.txt").reshape(-1, 2)


def test_geodesy_reference_moves_the_gps_route_only(tmp_path, capsys):
    mod = load_script(PKG / "scripts" / "generate_farm")
    cfg = tmp_path / "farm.yaml"
    cfg.write_text("rows: 3\nplants_per_row: 5\nplant_detail: low\nplant_variants: 2\n")
    assert mod.main(["--config", str(cfg), "--out", str(tmp_path / "default")]) == 0
    assert mod.main(["--config", str(cfg), "--out", str(tmp_path / "lubbock"),
                     "--geodesy-reference", "33.4", "-101.0", "0", "0"]) == 0
    world_d, gps_d = _route(tmp_path / "default")
    world_l, gps_l = _route(tmp_path / "lubbock")
    np.testing.assert_array_equal(world_d, world_l)                  # same farm
    for gps, ref in ((gps_d, (49.9, 8.9)), (gps_l, (33.4, -101.0))):
        assert np.all(np.abs(gps - np.array(ref)) < 1e-3)             # near its reference
        x, y, _ = HectorGeodesy(*ref).geodetic_to_world(gps[:, 0], gps[:, 1])
        np.testing.assert_allclose(np.stack([x, y], axis=1), world_d, atol=1e-6)


def test_bad_geodesy_reference_exits_2_with_a_message(tmp_path, capsys):
    mod = load_script(PKG / "scripts" / "generate_farm")
    assert mod.main(["--out", str(tmp_path / "x"), "--geodesy-reference", "95", "0", "0", "0"]) == 2
    assert "reference_latitude_deg" in capsys.readouterr().err
