"""The experiment record and report: trajectory log, route frames, report files."""
import csv
import json
import math

import numpy as np
import pytest

from cottonsim_experiments.recording.experiment import (TrajectoryLog, TrajectoryLogConfig, experiment_report,
                                                        planned_world_from_gps, planned_world_from_map,
                                                        sim_world_from_settings, summary_line, write_experiment)
from cottonsim_experiments.reproduce.packages import package_path
from cottonsim_navigation.waypoints.files import GpsWaypoint, MapWaypoint
from cottonsim_world.farm.model import Lane, Pose2D
from cottonsim_world.geodesy import HectorGeodesy


def test_log_keeps_finite_spaced_samples():
    log = TrajectoryLog(TrajectoryLogConfig(min_period_s=0.1))
    assert log.add(0.0, 1, 2, 0)
    assert not log.add(0.05, 1, 2, 0)            # too soon
    assert not log.add(0.2, float("nan"), 2, 0)  # NaN
    assert log.add(0.2, 1.5, 2, 0.1)
    assert not log.add(0.1, 0, 0, 0)             # back in time
    assert len(log) == 2 and log.duration_s == pytest.approx(0.2)
    assert log.array.shape == (2, 4)
    with pytest.raises(ValueError, match="min_period_s"):
        TrajectoryLogConfig(min_period_s=-1.0)


def test_map_route_goes_through_home():
    home = Pose2D(-6.0, 1.0, math.pi / 2)
    w = planned_world_from_map([MapWaypoint(3.95, -4.57), MapWaypoint(0.0, 0.0)], home)
    # 3.95 m ahead (world +y) and 4.57 m to the right (world +x)
    assert w[0] == pytest.approx([-6.0 + 4.57, 1.0 + 3.95])
    assert w[1] == pytest.approx([-6.0, 1.0])


def test_gps_route_uses_the_sim_geodesy():
    g = HectorGeodesy()
    lat, lon, _ = g.world_to_geodetic(-1.43, 4.95, 0.0)
    w = planned_world_from_gps([GpsWaypoint(lat, lon)], g)
    assert w[0] == pytest.approx([-1.43, 4.95], abs=1e-6)


def _straight_run(offset_m):
    """A run up lane x = 0 (y 0..10), driven offset_m to the side; waypoints on the lane centre."""
    planned = np.array([[0.0, 0.0], [0.0, 5.0], [0.0, 10.0]])
    t = np.linspace(0, 20, 201)
    traj = np.stack([t, np.full_like(t, offset_m), t / 2.0, np.full_like(t, math.pi / 2)], axis=1)
    lanes = [Lane(0, 0.0, 2.0, 8.0), Lane(1, 5.0, 2.0, 8.0)]
    return planned, traj, lanes


def test_map_report_errors_and_cross_track():
    planned, traj, lanes = _straight_run(0.15)
    r = experiment_report("map", planned, traj, 20.0, 10.0, plant_contacts=2, lanes=lanes)
    assert r["ae_m"] == pytest.approx(0.15) and r["rmse_m"] == pytest.approx(0.15)
    assert r["cr_percent"] == 100.0                 # within 0.25 m
    assert r["cr_percent_010m"] == 0.0              # but not within 0.10 m
    assert r["cross_track_mean_m"] == pytest.approx(0.15) and r["cross_track_max_m"] == pytest.approx(0.15)
    assert r["real_time_factor"] == pytest.approx(2.0) and r["plant_contacts"] == 2


def test_gps_report_in_degrees_and_metres(tmp_path):
    g = HectorGeodesy()
    planned, traj, lanes = _straight_run(0.3)
    planned = planned + [-3.0, 10.0]
    traj[:, 1:3] += [-3.0, 10.0]
    lat, lon, _ = g.world_to_geodetic(planned[:, 0], planned[:, 1], np.zeros(3))
    latlon = np.stack([lat, lon], axis=1)
    r = write_experiment(str(tmp_path / "run"), "gps", planned, traj, 20.0, 40.0, 0, lanes=None,
                         plant_xy=np.array([[-2.0, 15.0]]), geodesy=g, planned_latlon=latlon, run_name="t",
                         waypoints_file="w.txt", navigator={"state": "finished"})
    e_deg = math.degrees(0.3 / g.radius_north_m)   # 0.3 m along world x = north, in degrees of latitude
    assert e_deg < 5e-6                             # so the paper's GPS CR counts them all
    assert r["cr_percent"] == 100.0 and r["cr_threshold"] == 5e-6
    assert r["ae_m"] == pytest.approx(0.3) and r["cr_percent_010m"] == 0.0
    saved = json.loads((tmp_path / "run" / "report.json").read_text())
    assert saved["complete"] is True and saved["navigator"] == {"state": "finished"}
    assert saved["ae_m"] == pytest.approx(0.3)
    rows = list(csv.reader(open(tmp_path / "run" / "trajectory.csv")))
    assert rows[0] == ["t_s", "x_m", "y_m", "yaw_rad", "lat_deg", "lon_deg"] and len(rows) == 202
    assert float(rows[1][4]) == pytest.approx(lat[0] + e_deg, abs=1e-9)
    assert (tmp_path / "run" / "trajectory.png").stat().st_size > 1000
    assert "CR 100.0 %" in summary_line(r)


def test_incomplete_run_without_trajectory_still_writes(tmp_path):
    r = write_experiment(str(tmp_path / "x"), "map", np.array([[0.0, 0.0]]), np.zeros((0, 4)), 0.0, 0.0,
                         complete=False, incomplete_reason="killed", plot=False)
    assert r["ae_m"] is None and r["complete"] is False and r["incomplete_reason"] == "killed"
    assert json.loads((tmp_path / "x" / "report.json").read_text())["waypoints"] == 1
    assert "INCOMPLETE" in summary_line(r)
    with pytest.raises(ValueError, match="mode"):
        experiment_report("lidar", [[0, 0]], np.zeros((1, 4)), 1.0, 1.0)


def test_sim_world_matches_the_default_farm():
    w = sim_world_from_settings({})
    assert (w.home.x_m, w.home.y_m) == (-6.0, 1.0)
    assert len(w.plant_xy) == 180 and len(w.lanes) == 10
    assert w.lanes[0].x_m == pytest.approx(-1.43)
    with pytest.raises(ValueError, match="farm"):
        sim_world_from_settings({"farm": {"rows_per_field": 3}})


def test_committed_lanes_file_is_the_default_farms_lane_centres():
    import pathlib
    from cottonsim_experiments.recording.experiment import farm_lanes_gps, sim_world_from_settings
    from cottonsim_navigation.waypoints.files import load_gps_lanes
    world = sim_world_from_settings({})
    lanes = farm_lanes_gps(world)
    committed = load_gps_lanes(pathlib.Path(package_path("cottonsim_navigation")) / "config/waypoints/farm_lanes_gps.txt")
    assert len(committed) == len(world.lanes) == len(lanes)
    for (a, b), lane in zip(committed, world.lanes):
        # back through the simulator's geodesy: the lane's ends in the world frame
        x, y, _ = world.geodesy.geodetic_to_world(np.array([a.lat, b.lat]), np.array([a.lon, b.lon]), np.zeros(2))
        assert np.allclose(x, lane.x_m, atol=1e-6)
        assert np.allclose(y, [lane.y_start_m, lane.y_end_m], atol=1e-6)
