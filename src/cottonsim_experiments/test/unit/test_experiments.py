"""The experiment plans, summaries and the results page (no ROS, no simulator runs; the route and row-spacing
runs go through the sweep engine on the local 2-CPU Ray cluster of conftest.py, with a stub launcher)."""
import csv
import functools
import json
import math
import os

import pytest
import yaml

from cottonsim_experiments.reproduce import row_spacing as rs
from cottonsim_experiments.reproduce.launcher import LaunchSpec, ProgressParser
from cottonsim_experiments.reproduce.results_doc import render_results
from cottonsim_experiments.reproduce.route_experiments import run_route, run_row_spacing
from cottonsim_experiments.reproduce.runs import Workspace, compare_reports, deep_merge, write_sim_config
from cottonsim_experiments.sweep.engine import EngineConfig
from cottonsim_experiments.sweep.spec import run_id
from cottonsim_experiments.reproduce.seeds import aggregate_reports, format_spread, spread
from cottonsim_world.farm.config import FarmConfig


# ----------------------------------------------------------------- row spacing
def test_study_config_defaults_are_the_papers_ten_spacings_and_bad_values_are_named():
    c = rs.RowSpacingStudyConfig()
    assert c.spacings_m == pytest.approx([1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9])
    for kwargs, name in ((dict(spacings_m=()), "spacings_m"), (dict(spacings_m=(1.0, -1.0)), "spacings_m"),
                         (dict(rows=1), "rows"), (dict(goal_timeout_s=0.0), "goal_timeout_s"),
                         (dict(seed=-1), "seed"), (dict(lane_x_m=math.nan), "lane_x_m")):
        with pytest.raises(ValueError, match=name):
            rs.RowSpacingStudyConfig(**kwargs)


@pytest.mark.parametrize("spacing", [1.0, 1.35, 1.9])
def test_attempt_farm_puts_the_driven_lane_ahead_of_home_between_two_rows(spacing):
    config = rs.RowSpacingStudyConfig()
    farm = FarmConfig.from_dict(rs.attempt_farm_settings(config, spacing))   # narrow farms are allowed
    assert farm.lane_x_m(1) == pytest.approx(config.lane_x_m)
    # the rows beside lane 1 are half a spacing away on either side
    assert farm.row_x_m(0) - farm.lane_x_m(1) == pytest.approx(spacing / 2)
    assert farm.lane_x_m(1) - farm.row_x_m(1) == pytest.approx(spacing / 2)
    route = rs.attempt_route_world(farm)
    assert [x for x, _ in route] == pytest.approx([config.lane_x_m] * 3)
    ys = [y for _, y in route]
    last_stem = farm.first_plant_y_m + 0.7 * 19
    assert ys[0] == pytest.approx(farm.first_plant_y_m - farm.route_entry_distance_m)
    assert ys[1] == pytest.approx((farm.first_plant_y_m + last_stem) / 2)
    assert ys[2] == pytest.approx(last_stem + farm.route_exit_distance_m)


def _report(reached=3, waypoints=3, contacts=0, complete=True, reason="route complete", aborted=0):
    return {"waypoints": waypoints, "reached": reached, "plant_contacts": contacts, "complete": complete,
            "sim_duration_s": 60.0, "cross_track_max_m": 0.04,
            "navigator": {"reason": reason, "aborted": aborted}}


def test_outcome_classification_names_why_an_attempt_failed():
    ok = rs.outcome_from_report(1.8, 0.7, _report())
    assert ok.traversed and ok.reason == "" and ok.free_lane_m == pytest.approx(1.1)
    blocked = rs.outcome_from_report(1.2, 0.7, _report(reached=1, aborted=1, reason="goal 2 aborted: no path"))
    assert not blocked.traversed and "1/3 waypoints reached" in blocked.reason and "no path" in blocked.reason
    scraped = rs.outcome_from_report(1.5, 0.7, _report(contacts=4))
    assert not scraped.traversed and "4 plant contacts" in scraped.reason
    stuck = rs.outcome_from_report(1.0, 0.7, _report(reached=1, aborted=1, contacts=9), progress=(2.5, 13.3))
    assert stuck.reason.startswith("stopped 2.5 m into the 13.3 m row") and stuck.lane_progress_m == 2.5
    farm = FarmConfig(plants_per_row=5)                 # stems from 8.95 to 11.75 m
    assert rs.lane_progress_m([1.0, 9.95, 9.0], farm) == (pytest.approx(1.0), pytest.approx(2.8))
    assert rs.lane_progress_m([1.0, 30.0], farm)[0] == pytest.approx(2.8)
    missing = rs.outcome_from_report(1.0, 0.7, None, "wall-clock limit reached")
    assert not missing.traversed and "wall-clock" in missing.reason


def test_contact_free_spacing_is_robot_width_plus_both_collision_radii():
    assert rs.contact_free_spacing_m(0.67, 0.25) == pytest.approx(1.17)
    summary = rs.study_summary(rs.RowSpacingStudyConfig(spacings_m=(1.8,)), [rs.outcome_from_report(1.8, 0.7, _report())],
                               0.67, 0.25)
    assert summary["contact_free_spacing_m"] == pytest.approx(1.17)


def test_smallest_traversable_spacing_needs_every_wider_spacing_to_pass():
    def o(s, ok):
        return rs.outcome_from_report(s, 0.7, _report() if ok else _report(contacts=1))
    # 1.2 passes by luck but 1.3 fails: the answer is the bottom of the run that reaches the widest
    outcomes = [o(1.0, False), o(1.2, True), o(1.3, False), o(1.4, True), o(1.5, True), o(1.6, True)]
    assert rs.smallest_traversable_spacing(outcomes) == pytest.approx(1.4)
    assert rs.smallest_traversable_spacing([o(1.8, True), o(1.9, False)]) is None
    summary = rs.study_summary(rs.RowSpacingStudyConfig(spacings_m=(1.0, 1.2, 1.3, 1.4, 1.5, 1.6)), outcomes, 0.67)
    text = rs.summary_markdown(summary)
    assert "**1.40 m**" in text and "| 1.30 | 0.60 | no |" in text


# ----------------------------------------------------------------------- seeds
def test_spread_is_mean_and_sample_std_and_drops_non_finite_values():
    s = spread([1.0, 2.0, 3.0, float("nan")])
    assert (s["n"], s["n_dropped"], s["mean"], s["min"], s["max"]) == (3, 1, 2.0, 1.0, 3.0)
    assert s["std"] == pytest.approx(1.0)                 # sample std of 1, 2, 3
    assert spread([5.0])["std"] == 0.0
    assert math.isnan(spread([])["mean"])
    agg = aggregate_reports([{"ae_m": 0.1}, {"ae_m": 0.3, "rmse_m": 0.2}])
    assert agg["ae_m"]["mean"] == pytest.approx(0.2)
    assert agg["rmse_m"]["n"] == 1 and agg["rmse_m"]["n_dropped"] == 1   # the first report lacks it
    assert "cr_percent" not in agg
    assert format_spread(agg["ae_m"], 100.0, 1) == "20.0 ± 14.1 (10.0..30.0, n=2)"


# ------------------------------------------------------------------------ runs
def test_deep_merge_and_sim_config_file(tmp_path):
    base = {"seed": 0, "farm": {"rows": 9, "row_spacing_m": 1.8}, "lidar": {"samples_per_ring": 440}}
    merged = deep_merge(base, {"seed": 3, "farm": {"seed": 3}})
    assert merged == {"seed": 3, "farm": {"rows": 9, "row_spacing_m": 1.8, "seed": 3},
                      "lidar": {"samples_per_ring": 440}}
    assert base["farm"] == {"rows": 9, "row_spacing_m": 1.8}          # input untouched
    src = tmp_path / "base.yaml"
    src.write_text(yaml.safe_dump(base))
    out = write_sim_config(str(src), {"farm": {"seed": 5}}, str(tmp_path / "x" / "sim.yaml"))
    assert yaml.safe_load(open(out))["farm"]["seed"] == 5
    src.write_text(yaml.safe_dump(base))
    for bad, name in (({"farm": {"row_spacing_m": -1.0}}, "row_spacing_m"), ({"lidarr": {}}, "lidarr")):
        with pytest.raises(ValueError, match=name):        # refused before anything is written
            write_sim_config(str(src), bad, str(tmp_path / "bad.yaml"))
        assert not (tmp_path / "bad.yaml").exists()
    src.write_text("- not a mapping\n")
    with pytest.raises(ValueError, match="mapping"):
        write_sim_config(str(src), {}, str(tmp_path / "y.yaml"))


def test_compare_reports_flags_figures_outside_tolerance():
    a = {"cr_percent": 100.0, "ae_m": 0.050, "rmse_m": 0.060, "reached": 30, "plant_contacts": 0}
    assert compare_reports(a, dict(a, ae_m=0.052))["matches"]
    diff = compare_reports(a, dict(a, ae_m=0.070, reached=29))
    assert not diff["matches"] and set(diff["differences"]) == {"ae_m", "reached"}


def _launcher(reports):
    """The stub launcher (sweep_stub_runs.stub_launch: the Ray workers import it) with run name -> report."""
    import sweep_stub_runs
    return functools.partial(sweep_stub_runs.stub_launch, reports=reports)


def _launch_args(run_folder):
    return json.load(open(os.path.join(run_folder, "launch_args.json")))


def _workspace(tmp_path):
    return Workspace(results=str(tmp_path / "results"))


def test_route_runs_per_seed_as_a_sweep_and_summarises_the_spread(ray_cluster, tmp_path):
    ws = _workspace(tmp_path)
    good = dict(_report(30, 30), cr_percent=100.0, ae_m=0.04, rmse_m=0.05, mode="gps")
    worse = dict(_report(30, 30), cr_percent=100.0, ae_m=0.06, rmse_m=0.07, mode="gps")
    summary = run_route(ws, "gps_route", [0, 1, 2], record_bag=False,
                        launcher=_launcher({"seed_0": good, "seed_1": worse}), log=lambda s: None)
    out = tmp_path / "results" / "gps_route"
    assert sorted(p for p in os.listdir(out) if p.startswith("seed_")) == ["seed_0", "seed_1", "seed_2"]
    sim = yaml.safe_load(open(out / "seed_1" / "sim.yaml"))
    assert sim["seed"] == 1 and sim["farm"]["seed"] == 1
    assert sim["cameras"]["realsense_p"]["enabled"] is False        # the experiment's base settings kept
    assert _launch_args(out / "seed_1")["run_name"] == "seed_1"
    assert summary["runs_with_report"] == 2 and not summary["all_complete"]
    assert summary["spread"]["ae_m"]["mean"] == pytest.approx(0.05)
    assert json.load(open(out / "summary.json"))["seeds"] == [0, 1, 2]
    # the sweep's tables, and the run's whole folder (the plot) moved next to its report
    rows = list(csv.DictReader(open(out / "runs.csv")))
    assert [(r["run_id"], r["status"]) for r in rows] == [("seed_0", "done"), ("seed_1", "done"),
                                                          ("seed_2", "failed")]
    assert (out / "seed_0" / "trajectory.png").read_bytes().startswith(b"\x89PNG")
    assert summary["runs"][0]["run_dir"] == str(out / "seed_0")
    assert not (out / ".attempts").exists()
    with pytest.raises(ValueError, match="experiment"):
        run_route(ws, "boat_route", [0], launcher=_launcher({}))


def test_route_runs_again_replace_their_folders_and_resume_keeps_them(ray_cluster, tmp_path):
    ws = _workspace(tmp_path)
    first = dict(_report(30, 30), cr_percent=100.0, ae_m=0.04, mode="gps")
    second = dict(first, ae_m=0.09)
    run_route(ws, "gps_route", [0], record_bag=False, launcher=_launcher({"seed_0": first}), log=lambda s: None)
    again = run_route(ws, "gps_route", [0], record_bag=False, launcher=_launcher({"seed_0": second}),
                      log=lambda s: None)
    assert again["spread"]["ae_m"]["mean"] == pytest.approx(0.09)         # run again, folder replaced
    kept = run_route(ws, "gps_route", [0, 1], record_bag=False, launcher=_launcher({"seed_0": first, "seed_1": first}),
                     log=lambda s: None, engine=EngineConfig(resume=True))
    assert kept["runs"][0]["report"]["ae_m"] == pytest.approx(0.09)          # seed 0 kept, seed 1 run
    assert kept["runs_with_report"] == 2


def test_route_runs_with_vision_by_default_and_without_into_its_own_folder(ray_cluster, tmp_path):
    ws = _workspace(tmp_path)
    report = dict(_report(30, 30), cr_percent=100.0, ae_m=0.05, rmse_m=0.06, mode="gps")
    on = run_route(ws, "gps_route", [0], record_bag=False, launcher=_launcher({"seed_0": report}), log=lambda s: None)
    off = run_route(ws, "gps_route", [0], record_bag=False, launcher=_launcher({"seed_0": report}), vision=False,
                    log=lambda s: None)
    results = tmp_path / "results"
    assert _launch_args(results / "gps_route" / "seed_0")["vision"] == "true"
    assert _launch_args(results / "gps_route_no_vision" / "seed_0")["vision"] == "false"
    assert (on["vision"], off["vision"]) == (True, False)
    assert os.path.isfile(results / "gps_route" / "summary.json")
    assert os.path.isfile(results / "gps_route_no_vision" / "summary.json")


def test_map_route_seeds_the_simulator_only_and_keeps_the_mapped_farm(ray_cluster, tmp_path):
    ws = _workspace(tmp_path)
    report = dict(_report(30, 30), cr_percent=100.0, ae_m=0.04, rmse_m=0.05, mode="map")
    run_route(ws, "map_route", [1, 2], record_bag=False, launcher=_launcher({"seed_1": report, "seed_2": report}),
              log=lambda s: None)
    base = yaml.safe_load(open(os.path.join(ws.experiments, "config", "sim_navigation.yaml")))
    for seed in (1, 2):
        sim = yaml.safe_load(open(tmp_path / "results" / "map_route" / f"seed_{seed}" / "sim.yaml"))
        assert sim["seed"] == seed                                   # sensor noise, solver order vary
        assert sim.get("farm") == base.get("farm")                   # the farm the shipped map shows
        assert (sim.get("farm") or {}).get("seed", 0) == 0           # (farm seed 0, the default)
    assert _launch_args(tmp_path / "results" / "map_route" / "seed_1")["waypoints"].endswith("route_map.csv")


def _spacing_run(seed, spacing):
    return run_id(seed, {"row_spacing_m": spacing})


def test_row_spacing_study_writes_gps_routes_in_the_tested_lane_and_a_summary(ray_cluster, tmp_path):
    ws = _workspace(tmp_path)
    config = rs.RowSpacingStudyConfig(spacings_m=(1.2, 1.8))
    reports = {_spacing_run(0, 1.2): _report(1, 3, aborted=1, reason="no path"), _spacing_run(0, 1.8): _report()}
    summary = run_row_spacing(ws, config, launcher=_launcher(reports), log=lambda s: None)
    assert summary["smallest_traversable_spacing_m"]["mean"] == pytest.approx(1.8)
    assert summary["per_seed"][0]["smallest_traversable_spacing_m"] == pytest.approx(1.8)
    from cottonsim_world.geodesy import HectorGeodesy
    geo = HectorGeodesy()
    run_folder = tmp_path / "results" / "row_spacing" / "runs" / _spacing_run(0, 1.2)
    args = _launch_args(run_folder)
    assert os.path.basename(args["waypoints"]) == "route_gps.txt"          # written by the run, kept with it
    lines = [l.split() for l in open(run_folder / "route_gps.txt") if not l.startswith("#")]
    xs = [geo.geodetic_to_world(float(lat), float(lon))[0] for lat, lon in lines]
    assert xs == pytest.approx([config.lane_x_m] * 3, abs=1e-6)
    assert json.load(open(run_folder / "outcome.json"))["waypoints_file"] == "route_gps.txt"
    farm = yaml.safe_load(open(run_folder / "sim.yaml"))["farm"]
    assert farm["row_spacing_m"] == 1.2 and farm["require_lane_fit"] is False and farm["rows"] == 2
    assert args["on_failure"] == "stop" and args["vision"] == "false"
    assert "| 1.20 | 0.50 | no |" in open(tmp_path / "results" / "row_spacing" / "seed_0" / "summary.md").read()
    assert "| 1.20 | 0.50 | 0/1 | 0.0 |" in open(tmp_path / "results" / "row_spacing" / "summary.md").read()
    rows = list(csv.DictReader(open(tmp_path / "results" / "row_spacing" / "runs" / "runs.csv")))
    assert [r["row_spacing_m"] for r in rows] == ["1.2", "1.8"]


def test_row_spacing_over_seeds_reports_the_spread_of_the_answer(ray_cluster, tmp_path):
    ws = _workspace(tmp_path)
    config = rs.RowSpacingStudyConfig(spacings_m=(1.2, 1.5, 1.8))
    # seed 0: 1.2 fails; seed 4: everything passes; seed 7: even 1.8 fails (no answer)
    outcomes = {0: [_report(contacts=2), _report(), _report()],
                4: [_report(), _report(), _report()],
                7: [_report(contacts=1), _report(contacts=1), _report(reached=2)]}
    reports = {_spacing_run(seed, sp): rep for seed, reps in outcomes.items()
               for sp, rep in zip(config.spacings_m, reps)}
    summary = run_row_spacing(ws, config, launcher=_launcher(reports), seeds=[0, 4, 7], log=lambda s: None)
    for seed in (0, 4, 7):
        sim = yaml.safe_load(open(tmp_path / "results" / "row_spacing" / "runs" / _spacing_run(seed, 1.5) / "sim.yaml"))
        assert sim["seed"] == seed and sim["farm"]["seed"] == seed
    assert summary["seeds"] == [0, 4, 7] and summary["seeds_without_answer"] == 1
    st = summary["smallest_traversable_spacing_m"]
    assert (st["n"], st["mean"], st["min"], st["max"]) == (2, pytest.approx(1.35), 1.2, 1.5)
    rows = {round(r["spacing_m"], 2): r for r in summary["spacings"]}
    assert (rows[1.2]["traversed"], rows[1.5]["traversed"], rows[1.8]["traversed"]) == (1, 2, 2)
    assert rows[1.2]["plant_contacts_mean"] == pytest.approx(1.0)
    text = rs.seeds_markdown(summary)
    assert "**1.35 m** (± 0.21 m over 2 seeds, 1.20..1.50)" in text and "1 of 3 seeds had no traversable" in text


# ----------------------------------------------------------------- results page
def test_results_page_is_generated_from_the_results_folders(ray_cluster, tmp_path):
    ws = _workspace(tmp_path)
    reports = [dict(_report(30, 30), cr_percent=100.0, ae_m=0.04, rmse_m=0.05, sim_duration_s=540.0, mode="gps"),
               dict(_report(30, 30), cr_percent=100.0, ae_m=0.06, rmse_m=0.07, sim_duration_s=600.0, mode="gps")]
    run_route(ws, "gps_route", [0, 1], record_bag=False, launcher=_launcher({"seed_0": reports[0], "seed_1": reports[1]}),
              log=lambda s: None)
    run_row_spacing(ws, rs.RowSpacingStudyConfig(spacings_m=(1.5, 1.6)), log=lambda s: None,
                    launcher=_launcher({_spacing_run(0, 1.5): _report(contacts=2), _spacing_run(0, 1.6): _report()}))
    doc = tmp_path / "docs" / "results.md"
    text = render_results(ws.results, str(doc))
    assert doc.read_text() == text
    assert "| AE [m] | 0.050 ± 0.014 (0.040..0.060, n=2) | 0.137" not in text     # that is the map route's paper value
    assert "| AE [m] | 0.050 ± 0.014 (0.040..0.060, n=2) | 0 (in degrees) |" in text
    assert "| route time (sim) [min] | 9.50 ± 0.71 (9.00..10.00, n=2) | 20 min 42 s | <= 10 min |" in text
    assert "**1.60 m**" in text
    assert "## Map-based route" in text and "No results yet" in text       # map route not run here


def test_progress_parser_follows_the_navigator_log():
    p = ProgressParser()
    assert p.feed("[INFO] [12.3]: gps_waypoint_navigator: goal 3/30 entry (1.00, 2.00, yaw 0.00) sent")
    assert p.text == "waypoint 3/30"
    assert not p.feed("[INFO] something else")
    assert p.feed("gps_waypoint_navigator: finished (route complete): 30/30 waypoints succeeded")
    assert p.text.startswith("navigator finished (route complete")
    with pytest.raises(ValueError, match="wall_timeout_s"):
        LaunchSpec("cottonsim_navigation", "x.launch", wall_timeout_s=0.0)
    assert LaunchSpec("p", "f.launch", {"a": 1}).command(12345) == ["roslaunch", "-p", "12345", "p", "f.launch", "a:=1"]


def test_screenshot_bringups_resolve_their_launch_arguments():
    """$(find pkg) in a bringup's arguments becomes the package's folder (roslaunch gets a list, no shell)."""
    from cottonsim_experiments.reproduce.packages import package_path
    from cottonsim_experiments.reproduce.screenshots import BRINGUPS, image_is_blank, resolve_find
    assert resolve_find("$(find cottonsim_world)/config/sim_in_lane.yaml", find=lambda pkg: f"/ws/{pkg}") == \
        "/ws/cottonsim_world/config/sim_in_lane.yaml"
    assert resolve_find(1.5) == "1.5"
    for name, (launches, (rviz_pkg, rviz_rel), _) in BRINGUPS.items():
        assert os.path.isfile(os.path.join(package_path(rviz_pkg), rviz_rel)), name
        for pkg, launch_file, args in launches:
            assert os.path.isfile(os.path.join(package_path(pkg), "launch", launch_file)), name
            for value in args.values():
                resolved = resolve_find(value)
                if resolved.endswith(".yaml"):
                    assert os.path.isfile(resolved), (name, resolved)
    assert image_is_blank(os.path.join(package_path("cottonsim_experiments"), "does_not_exist.png"))
