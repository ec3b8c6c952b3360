"""``reproduce harvest`` without a bringup: the route file, the missing-module error, the tables, the launch switch."""
import json
import pathlib
import sys
import xml.etree.ElementTree as ET

import pytest

from cottonsim_navigation.waypoints.files import load_gps_waypoints
from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.geodesy import HectorGeodesy

from cottonsim_common.config.yaml_files import load_yaml_file
from cottonsim_experiments.harvest_run.evaluation import HarvestEvaluationError
from cottonsim_experiments.reproduce.harvest import (figures_table, harvest_runs, run_harvest, summary_markdown,
                                                     write_harvest_route)
from cottonsim_experiments.reproduce.results_doc import render_results
from cottonsim_experiments.reproduce.route_experiments import farm_of_run
from cottonsim_experiments.reproduce.runs import Workspace, write_sim_config

PACKAGE = pathlib.Path(__file__).resolve().parents[2]


def test_the_route_file_lies_on_the_lanes_of_the_runs_farm(tmp_path):
    sim = write_sim_config(str(PACKAGE / "config" / "sim_navigation.yaml"), {"farm": {"seed": 3}},
                           str(tmp_path / "sim.yaml"))
    path = write_harvest_route(None, sim, str(tmp_path), lanes="row", row=2)
    farm = farm_of_run(sim)
    geodesy = HectorGeodesy(*simulator_config_from_dict(load_yaml_file(sim)).geodesy_reference)
    points = [geodesy.geodetic_to_world(w.lat, w.lon, 0.0)[:2] for w in load_gps_waypoints(path)]
    assert len(points) == 6
    for (x, y), lane in zip(points, [2, 2, 2, 3, 3, 3]):
        assert x == pytest.approx(farm.lane_x_m(lane), abs=1e-3)
    assert points[0][1] < farm.first_plant_y_m < farm.last_plant_y_m < points[2][1]
    assert points[3][1] > farm.last_plant_y_m and points[5][1] < farm.first_plant_y_m


def test_runs_carry_the_harvest_launch_arguments_and_bad_choices_are_named():
    runs = harvest_runs([0, 2], "ground_truth", False, 0.0, True, 600.0).runs()
    assert [r.seed for r in runs] == [0, 2]
    assert runs[0].launch_args == {"harvest": True, "harvest_targets": "ground_truth", "vision": False}
    with pytest.raises(ValueError, match="vision must be on"):
        harvest_runs([0], "detections", False, 0.0, True, 600.0)
    with pytest.raises(ValueError, match="targets must be one of"):
        harvest_runs([0], "oracle", True, 0.0, True, 600.0)


def test_without_the_metrics_module_no_run_starts_and_no_figure_is_written(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "cottonsim_experiments.harvest.metrics", None)    # import fails

    def launcher(*_a, **_k):
        raise AssertionError("no bringup may start without the figures' module")
    with pytest.raises(HarvestEvaluationError, match="cottonsim_experiments.harvest.metrics"):
        run_harvest(Workspace(results=str(tmp_path)), [0], targets="ground_truth", launcher=launcher)
    assert not (tmp_path / "harvest_ground_truth" / "summary.json").exists()


FIGURES = {"open_bolls": 40, "reachable": 30, "detected": 29, "attempted": 28, "picked": 27, "in_bin": 27,
           "harvest_success_percent": 90.0, "field_harvest_percent": 67.5, "cycle_time_s": {"median": 5.5, "p95": 9.0},
           "bolls_per_hour": 120.0, "bolls_per_hour_picking": 600.0,
           "localization_error_m": {"median": 0.004, "p95": 0.012}, "arm_stem_contacts": 0, "arm_leaf_contacts": 3,
           "base_plant_contacts": 0, "route_time_s": 810.0, "real_time_factor": 0.7,
           "funnel": [{"stage": "reachable", "count": 30, "percent_of_previous": None},
                      {"stage": "bin", "count": 27, "percent_of_previous": 100.0}]}


def test_tables_show_each_figure_with_its_unit_and_a_dash_for_none():
    lines = figures_table({"seed 0": FIGURES, "seed 1": None})
    text = "\n".join(lines)
    assert "| harvest success [% of reachable] | 90.0 | - |" in text
    assert "| localisation error, median [mm] | 4.0 | - |" in text
    assert "| route time (sim) [min] | 13.50 | - |" in text
    summary = {"lanes": "row 1 from both lanes", "targets": "ground_truth", "pooled": FIGURES,
               "runs": [{"seed": 0, "figures": FIGURES}, {"seed": 1, "figures": None, "error": "no report"}],
               "anchors": {"Bac et al. 2014": {"cycle_time_s": 33.0}}}
    md = summary_markdown(summary)
    assert "- Bac et al. 2014: cycle_time_s 33.0" in md and "reachable 30 -> bin 27 (100 %)" in md
    assert "- seed 1: no report" in md


def test_results_page_has_the_harvest_section_from_the_summary(tmp_path):
    results = tmp_path / "results"
    (results / "harvest_ground_truth").mkdir(parents=True)
    summary = {"lanes": "row 1 from both lanes", "targets": "ground_truth", "pooled": FIGURES,
               "runs": [{"seed": 0, "figures": FIGURES, "run_dir": str(results / "nowhere")}],
               "anchors": {"Fue et al. 2020": {"harvest_success_percent": 78.5}}}
    (results / "harvest_ground_truth" / "summary.json").write_text(json.dumps(summary))
    text = render_results(str(results), str(tmp_path / "doc" / "results.md"))
    section = text[text.index("## Harvest"):]
    assert "### Targets from ground truth (a study option)" in section
    assert "### Targets from the networks' detections\n\nNo runs in this results folder" in section
    assert "| in the bin | 27 | 27 |" in section and "Fue et al. 2020: harvest_success_percent 78.5" in section
    empty = render_results(str(tmp_path / "none"), str(tmp_path / "doc2" / "results.md"))
    assert "## Harvest" in empty and "No results yet" in empty[empty.index("## Harvest"):]


def test_results_doc_sections_renders_the_harvest_again_and_keeps_the_other_sections(tmp_path):
    doc = tmp_path / "doc" / "results.md"
    doc.parent.mkdir()
    doc.write_text("# Results\n\nheader kept\n\n## GPS-based route (the paper's section 3.3)\n\n| CR | 100 % |\n\n"
                   "## Harvest (issue: the robot picks the cotton)\n\nNo results yet: run the command above.\n\n"
                   "## Something after\n\nkept too\n")
    results = tmp_path / "results"
    (results / "harvest").mkdir(parents=True)
    summary = {"lanes": "row 1 from both lanes", "targets": "detections", "pooled": FIGURES,
               "runs": [{"seed": 0, "figures": FIGURES, "run_dir": str(results / "nowhere")}], "anchors": {}}
    (results / "harvest" / "summary.json").write_text(json.dumps(summary))
    text = render_results(str(results), str(doc), sections=["harvest"])
    assert text == doc.read_text()
    assert text.startswith("# Results\n\nheader kept\n") and "| CR | 100 % |" in text
    assert "## Something after\n\nkept too" in text
    harvest = text[text.index("## Harvest"):text.index("## Something after")]
    assert "### Targets from the networks' detections" in harvest and "No results yet" not in harvest
    assert text.count("## Harvest") == 1
    # a page without the section gets it appended; an unknown section is refused
    doc.write_text("# Results\n\n## GPS-based route (the paper's section 3.3)\n\nx\n")
    assert "### Targets from the networks' detections" in render_results(str(results), str(doc), ["harvest"])
    with pytest.raises(ValueError, match="unknown results section 'harvests'"):
        render_results(str(results), str(doc), ["harvests"])


@pytest.mark.parametrize("launch_file", ["gps_navigation.launch", "map_navigation.launch"])
def test_launch_switches_the_harvest_and_its_route_hold(launch_file):
    root = ET.parse(PACKAGE / "launch" / launch_file).getroot()
    args = {a.get("name"): a.get("default") for a in root.iter("arg") if a.get("default") is not None}
    assert args["harvest"] == "false" and args["harvest_targets"] == "detections"
    assert "not arg('harvest')" in args["boll_halt"]
    nav = [n for n in root.iter("node") if n.get("type", "").endswith("waypoint_navigator")][0]
    hold = [p for p in nav.iter("param") if p.get("name") == "hold_topic"][0]
    assert "/harvest/hold_route" in hold.get("value")
    max_age = [p for p in nav.iter("param") if p.get("name") == "route_hold/max_age_s"][0]
    assert max_age.get("if") == "$(arg harvest)"
    overlay = [r for r in root.iter("rosparam") if r.get("ns") == "harvest"][0]
    assert overlay.get("if") == "$(arg harvest)" and args["harvest_route_config"].endswith("harvest_route.yaml")
    speed = [r for r in root.iter("rosparam") if r.get("ns") == "move_base"][0]
    assert speed.get("if") == "$(arg harvest)" and args["harvest_move_base_config"].endswith("harvest_move_base.yaml")
    children = list(root)
    move_base = [i for i, c in enumerate(children) if "move_base.launch" in c.get("file", "")][0]
    assert children.index(speed) > move_base                    # loaded after move_base's own settings
    includes = [i for i in root.iter("include") if "harvest.launch" in i.get("file", "")]
    assert includes and includes[0].get("if") == "$(arg harvest)"
    assert [n for n in root.iter("node") if n.get("type") == "harvest_recorder"][0].get("if") == "$(arg harvest)"


def test_the_harvest_scans_the_lanes_slower_than_the_routes_drive():
    import yaml

    harvest = yaml.safe_load((PACKAGE / "config" / "harvest_move_base.yaml").read_text())
    nav = PACKAGE.parent / "cottonsim_navigation" / "config"
    for route in ("gps_navigation_move_base.yaml", "map_navigation_move_base.yaml"):
        route_speed = yaml.safe_load((nav / route).read_text())["DWAPlannerROS"]["max_vel_x"]
        assert 0.0 < harvest["DWAPlannerROS"]["max_vel_x"] < route_speed


def test_the_command_refuses_bad_requests_with_one_line(tmp_path, capsys, monkeypatch):
    from cottonsim_experiments.reproduce.cli import main

    assert main(["harvest", "--results", str(tmp_path), "--vision", "both"]) == 2
    assert "harvest takes --vision on or off" in capsys.readouterr().err
    assert main(["harvest", "--results", str(tmp_path), "--waypoints", str(tmp_path / "route.txt")]) == 2
    assert "--waypoints is for gps-route" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "cottonsim_experiments.harvest.metrics", None)
    assert main(["harvest", "--results", str(tmp_path), "--seeds", "0"]) == 2
    assert "cottonsim_experiments.harvest.metrics" in capsys.readouterr().err
