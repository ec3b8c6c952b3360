"""The harvest experiment's pure parts: its route, its record (harvest.json), the boll outcomes."""
import json
import math
import os

import pytest

from cottonsim_world.farm.config import FarmConfig

from cottonsim_experiments.harvest_run.outcomes import boll_outcomes, match_targets, run_totals
from cottonsim_experiments.harvest_run.record import HarvestRecord, write_json_atomic
from cottonsim_experiments.harvest_run.route import (harvest_lanes, lane_headings, rows_beside,
                                                     serpentine_route)

import numpy as np


# ------------------------------------------------------------------------------------------------ route
def test_row_route_drives_both_lanes_of_the_row_as_a_serpentine():
    farm = FarmConfig()
    lanes = harvest_lanes(farm, "row", row=1)
    assert lanes == [1, 2]
    route = serpentine_route(farm, lanes)
    assert [w.lane for w in route] == [1, 1, 1, 2, 2, 2]
    assert all(w.x_m == pytest.approx(farm.lane_x_m(w.lane)) for w in route)
    ys = [w.y_m for w in route]
    assert ys[0] == pytest.approx(farm.first_plant_y_m - farm.route_entry_distance_m)
    assert ys[2] == pytest.approx(farm.last_plant_y_m + farm.route_exit_distance_m)
    assert ys[0] < ys[1] < ys[2] and ys[3] > ys[4] > ys[5]          # north on lane 1, back south on lane 2
    assert lane_headings(route) == {1: pytest.approx(math.pi / 2), 2: pytest.approx(-math.pi / 2)}
    # row 1 lies between lanes 1 and 2; the plants facing them are of rows 0, 1 and 2
    assert farm.lane_x_m(2) < farm.row_x_m(1) < farm.lane_x_m(1)
    assert rows_beside(farm, lanes) == [0, 1, 2]


def test_all_lanes_is_the_whole_farm_and_bad_choices_are_named():
    farm = FarmConfig(rows=3)
    assert harvest_lanes(farm, "all") == [0, 1, 2, 3]
    assert len(serpentine_route(farm, harvest_lanes(farm, "all"))) == 12
    assert rows_beside(farm, [0]) == [0] and rows_beside(farm, [3]) == [2]
    with pytest.raises(ValueError, match="row must be"):
        harvest_lanes(farm, "row", row=3)
    with pytest.raises(ValueError, match="lanes must be one of"):
        harvest_lanes(farm, "some")
    with pytest.raises(ValueError, match="not a lane"):
        harvest_lanes(farm, [0, 7])
    with pytest.raises(ValueError, match="repeat"):
        harvest_lanes(farm, [1, 1])


# ----------------------------------------------------------------------------------------------- record
def _status(**kw):
    base = {"state": "idle", "target": None, "picked": 0, "cycle_times_s": []}
    base.update(kw)
    return json.dumps(base)


def test_record_keeps_start_and_end_bolls_and_each_cycle_time_with_its_target(tmp_path):
    rec = HarvestRecord()
    bolls = [{"id": 0, "plant": 3, "position": [1.0, 2.0, 0.5], "state": 0},
             {"id": 1, "plant": 3, "position": [1.1, 2.0, 0.6], "state": 0}]
    assert rec.on_bolls(1.0, bolls)
    assert not rec.on_bolls(1.5, bolls)                          # same states: no change
    assert rec.on_status(_status(state="picking", target=7), 2.0)
    assert not rec.on_status(_status(state="picking", target=7), 2.1)
    # the status moves on to the next target as the first one is binned: the order of the picks decides
    assert rec.on_status(_status(state="picking", target=3, picked=1, cycle_times_s=[5.5]), 8.0)
    moved = [dict(bolls[0], state=2), bolls[1]]
    assert rec.on_bolls(8.0, moved)
    targets = [{"id": 7, "position": [0, 0, 0], "position_world": [1.0, 2.0, 0.51], "state": 2, "attempts": 0,
                "last_result": "ok"},
               {"id": 3, "position": [0, 0, 0], "position_world": [1.1, 2.0, 0.6], "state": 1, "attempts": 0,
                "last_result": "", "first_seen_s": 3.5, "last_seen_s": 7.5}]
    assert rec.on_targets("odom", 8.0, targets)
    kept = {t["id"]: t for t in rec.to_dict()["targets"]}
    assert (kept[3]["first_seen_s"], kept[3]["last_seen_s"]) == (3.5, 7.5)
    assert kept[7]["last_seen_s"] is None                        # not sent: not invented
    assert rec.to_dict()["cycle_time_by_target_s"] == {"7": 5.5}
    duplicate = {"id": 2, "position": [0, 0, 0], "position_world": [1.0, 2.0, 0.52], "state": 2, "attempts": 0,
                 "last_result": ""}
    rec.on_targets("odom", 12.0, [targets[0], dict(targets[1], state=2, last_result="ok"), duplicate])
    rec.on_status(_status(state="idle", picked=2, cycle_times_s=[5.5, 4.0]), 12.0)
    # a picked target's world position stays the one of its pick
    later = [dict(targets[0], position_world=[9.0, 9.0, 9.0]), dict(targets[1], state=2, last_result="ok"), duplicate]
    rec.on_targets("odom", 9.0, later)
    data = rec.to_dict()
    assert data["targets"][2]["position_world"] == [1.0, 2.0, 0.51]
    assert data["targets"][2]["state"] == "picked"
    assert data["picked_order"] == [7, 3]
    assert data["cycle_time_by_target_s"] == {"7": 5.5, "3": 4.0}
    assert [b["state"] for b in data["bolls_start"]["bolls"]] == ["on_plant", "on_plant"]
    assert [b["state"] for b in data["bolls_end"]["bolls"]] == ["in_bin", "on_plant"]
    path = tmp_path / "run" / "harvest.json"
    write_json_atomic(str(path), data)
    assert json.loads(path.read_text()) == data
    assert os.listdir(path.parent) == ["harvest.json"]             # no temporary file left


def test_record_rejects_bad_messages_with_their_problem():
    rec = HarvestRecord()
    with pytest.raises(ValueError, match="not JSON"):
        rec.on_status("{", 0.0)
    with pytest.raises(ValueError, match="JSON object"):
        rec.on_status("[1]", 0.0)
    with pytest.raises(ValueError, match="boll 4 state"):
        rec.on_bolls(0.0, [{"id": 4, "plant": 0, "position": [0, 0, 0], "state": 9}])
    with pytest.raises(ValueError, match="target 2 position"):
        rec.on_targets("odom", 0.0, [{"id": 2, "position": [0, float("nan"), 0], "state": 0}])


# --------------------------------------------------------------------------------------------- outcomes
def test_match_is_one_to_one_nearest_first_and_within_the_radius():
    targets = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [1.0, 0.0, 0.0]])
    bolls = np.array([[0.012, 0.0, 0.0], [0.05, 0.0, 0.0]])
    assert match_targets(targets, bolls, 0.05) == {1: 0, 0: 1}
    assert match_targets(targets, bolls, 0.02) == {1: 0}
    with pytest.raises(ValueError, match="match_radius_m"):
        match_targets(targets, bolls, 0.0)


def _harvest():
    start = [{"id": i, "plant": p, "position": pos, "state": "on_plant"} for i, p, pos in
             ((0, 1, [0.0, 0.0, 0.5]), (1, 1, [0.3, 0.0, 0.5]), (2, 1, [0.6, 0.0, 0.5]), (3, 2, [0.9, 0.0, 0.5]),
              (4, 9, [5.0, 0.0, 0.5]))]
    start.append({"id": 5, "plant": 1, "position": [0.0, 0.5, 0.5], "state": "in_bin"})
    end_states = {0: "in_bin", 1: "on_plant", 2: "dropped", 3: "on_plant", 4: "on_plant", 5: "in_bin"}
    end = [dict(b, state=end_states[b["id"]]) for b in start]
    targets = [{"id": 10, "position_world": [0.0, 0.01, 0.5], "state": "picked", "attempts": 0, "last_result": "ok"},
               {"id": 11, "position_world": [0.3, 0.0, 0.52], "state": "abandoned", "attempts": 2,
                "last_result": "capture_missed"},
               {"id": 12, "position_world": [0.6, 0.0, 0.5], "state": "picked", "attempts": 0, "last_result": "ok"},
               {"id": 13, "position_world": [0.9, 0.0, 0.5], "state": "confirmed", "attempts": 0, "last_result": ""},
               {"id": 14, "position_world": None, "state": "confirmed", "attempts": 0, "last_result": ""},
               # an untried and a missed duplicate nearer to boll 0 than the target that picked it
               {"id": 15, "position_world": [0.0, 0.001, 0.5], "state": "confirmed", "attempts": 0, "last_result": ""},
               {"id": 16, "position_world": [0.0, 0.002, 0.5], "state": "abandoned", "attempts": 2,
                "last_result": "capture_missed"}]
    return {"bolls_start": {"bolls": start}, "bolls_end": {"bolls": end}, "targets": targets,
            "cycle_time_by_target_s": {"10": 4.5, "12": 6.0}}


def test_outcomes_from_the_record_and_the_truth():
    out = {o["boll_id"]: o for o in boll_outcomes(_harvest(), reachable_ids=[0, 1, 2], plant_ids={1, 2})}
    assert sorted(out) == [0, 1, 2, 3]                 # open at the start, of the plants asked for
    assert out[0]["in_bin"] and out[0]["picked"] and out[0]["attempted"] and out[0]["detected"]
    assert out[0]["cycle_time_s"] == 4.5 and out[0]["localization_error_m"] == pytest.approx(0.01)
    assert out[1]["attempted"] and not out[1]["picked"] and out[1]["reason"] == "capture_missed"
    assert out[1]["localization_error_m"] == pytest.approx(0.02)
    assert out[2]["picked"] and not out[2]["in_bin"] and out[2]["reason"] == "dropped"
    assert out[2]["cycle_time_s"] is None
    assert out[3]["detected"] and not out[3]["attempted"] and out[3]["localization_error_m"] is None
    assert [out[i]["reachable"] for i in range(4)] == [True, True, True, False]
    assert out[0]["position_m"] == [0.0, 0.0, 0.5]


def test_outcomes_fit_the_figures_records():
    from cottonsim_experiments.harvest import metrics
    outcomes = boll_outcomes(_harvest(), reachable_ids=[0, 1, 2])
    figures = metrics.harvest_figures(outcomes, run_totals(_report()))
    assert figures["in_bin"] == 1 and figures["open_bolls"] == 5


def _report():
    return {"sim_duration_s": 300.0, "real_time_factor": 0.8, "plant_contacts": 0, "arm_stem_contacts": 1,
            "arm_leaf_contacts": 12, "navigator": {"route_hold_time_s": 120.0}}


def test_run_totals_from_the_report_and_missing_counts_named():
    totals = run_totals(_report())
    assert totals == {"field_time_s": 300.0, "picking_time_s": 120.0, "arm_stem_contacts": 1,
                      "arm_leaf_contacts": 12, "base_plant_contacts": 0, "route_time_s": 300.0,
                      "real_time_factor": 0.8}
    report = _report()
    del report["arm_leaf_contacts"]
    with pytest.raises(ValueError, match="arm_leaf_contacts"):
        run_totals(report)
    with pytest.raises(ValueError, match="bolls_start"):
        boll_outcomes({"bolls_end": {"bolls": []}}, reachable_ids=[])
