"""rosrun cottonsim_experiments farm_lanes_gps: writes the farm's lane centre lines; bad settings exit 2 with one line."""
import pathlib

from cottonsim_common.testing import load_script
from cottonsim_experiments.reproduce.packages import package_path
from cottonsim_navigation.waypoints.files import load_gps_lanes

PKG = pathlib.Path(__file__).resolve().parents[2]
NAVIGATION = pathlib.Path(package_path("cottonsim_navigation"))


def test_default_farm_gives_the_committed_file_and_a_smaller_farm_fewer_lanes(tmp_path, capsys):
    mod = load_script(PKG / "scripts" / "farm_lanes_gps")
    out = tmp_path / "lanes.txt"
    assert mod.main([str(out)]) == 0
    committed = load_gps_lanes(NAVIGATION / "config/waypoints/farm_lanes_gps.txt")
    written = load_gps_lanes(out)
    assert [(a.lat, a.lon, b.lat, b.lon) for a, b in written] == \
        [(a.lat, a.lon, b.lat, b.lon) for a, b in committed]
    cfg = tmp_path / "sim.yaml"
    cfg.write_text("farm: {rows: 3}\n")
    assert mod.main([str(out), "--sim-config", str(cfg)]) == 0
    assert len(load_gps_lanes(out)) == 4            # two outer lanes + one between each pair of rows


def test_bad_settings_exit_2_with_a_message(tmp_path, capsys):
    mod = load_script(PKG / "scripts" / "farm_lanes_gps")
    cfg = tmp_path / "sim.yaml"
    cfg.write_text("farm: {rows: -3}\n")
    assert mod.main([str(tmp_path / "lanes.txt"), "--sim-config", str(cfg)]) == 2
    assert "farm_lanes_gps:" in capsys.readouterr().err
    assert mod.main([str(tmp_path / "lanes.txt"), "--sim-config", str(tmp_path / "missing.yaml")]) == 2
