"""Sweep files: parsing, refusals naming the key, expansion into runs with stable ids; the run records."""
import json
import os

import pytest

from cottonsim_experiments.sweep.records import Progress, finished_run_ids, write_run, write_tables
from cottonsim_experiments.sweep.spec import SweepConfigError, check_runs, parse_sweep, run_id


def _sweep(**extra):
    data = {"name": "t", "experiment": "gps_route", "seeds": [0, 1]}
    data.update(extra)
    return parse_sweep(data)


def test_grid_times_seeds_gives_every_run_once_with_nested_overrides():
    spec = _sweep(grid={"sim.gps.noise_std_m": [0.01, 0.05], "launch.vision": [True, False]},
                  fixed={"sim": {"farm": {"rows": 5}}})
    runs = spec.runs()
    assert len(runs) == 2 * 2 * 2
    assert len({r.run_id for r in runs}) == len(runs)
    first = runs[0]
    assert first.sim_overrides == {"gps": {"noise_std_m": 0.01}, "farm": {"rows": 5}}
    assert first.launch_args == {"vision": True}
    assert first.parameters == {"sim.gps.noise_std_m": 0.01, "launch.vision": True}
    assert first.run_id == "seed_0__gps.noise_std_m=0.01__vision=true"


def test_no_grid_is_one_run_per_seed():
    assert [r.run_id for r in _sweep().runs()] == ["seed_0", "seed_1"]


@pytest.mark.parametrize("data, key", [
    ({"experiment": "gps_route", "seeds": [0], "sedes": [1]}, "sedes"),
    ({"experiment": "gps_rout"}, "experiment"),
    ({"experiment": "gps_route", "seeds": []}, "seeds"),
    ({"experiment": "gps_route", "seeds": [0, 0]}, "seeds"),
    ({"experiment": "gps_route", "seeds": [-1]}, "seeds"),
    ({"experiment": "gps_route", "grid": {"gps.noise_std_m": [0.1]}}, "gps.noise_std_m"),
    ({"experiment": "gps_route", "grid": {"sim.gps.noise_std_m": 0.1}}, "sim.gps.noise_std_m"),
    ({"experiment": "gps_route", "grid": {"sim.gps.noise_std_m": []}}, "sim.gps.noise_std_m"),
    ({"experiment": "gps_route", "grid": {"launch.run_name": ["x"]}}, "launch.run_name"),
    ({"experiment": "gps_route", "grid": {"sim.a": [float("nan")]}}, "sim.a"),
    ({"experiment": "gps_route", "grid": {"sim.a": [[1, 2]]}}, "sim.a"),
    ({"experiment": "gps_route", "fixed": {"sim.a": 1}, "grid": {"sim.a": [2]}}, "sim.a"),
    ({"experiment": "gps_route", "wall_timeout_s": 0}, "wall_timeout_s"),
    ({"experiment": "gps_route", "real_time_factor": -1}, "real_time_factor"),
    ({"experiment": "gps_route", "record_bag": "yes"}, "record_bag"),
    ({"experiment": "gps_route", "name": "../x"}, "name"),
])
def test_bad_sweep_files_are_refused_naming_the_key(data, key):
    with pytest.raises(SweepConfigError, match=key.replace(".", r"\.").replace("[", r"\[")):
        parse_sweep(data)


def test_values_with_the_same_text_are_refused():
    with pytest.raises(SweepConfigError, match="same run id"):
        _sweep(grid={"sim.a": [1, "1"]}).runs()


def test_validator_failures_name_the_run():
    def validate(run):
        if run.seed == 1:
            raise ValueError("farm.rows must be >= 2")
    with pytest.raises(SweepConfigError, match="run seed_1: farm.rows"):
        check_runs(_sweep().runs(), validate)


def test_run_id_is_filesystem_safe():
    assert run_id(3, {"launch.waypoints_name": "a b/c"}) == "seed_3__waypoints_name=a_b_c"


def test_records_write_runs_tables_and_resume_state(tmp_path):
    spec = _sweep(grid={"sim.gps.noise_std_m": [0.01, 0.05]})
    runs = spec.runs()
    sweep_dir = str(tmp_path)
    report = {"complete": True, "cr_percent": 100.0, "ae_m": 0.05, "plant_contacts": 0}
    write_run(sweep_dir, runs[0], {"status": "done", "attempts": 1, "node": "n1",
                                   "files": {"report.json": json.dumps(report), "launch.log": "ok\n"}})
    write_run(sweep_dir, runs[1], {"status": "failed", "attempts": 3, "error": "no report", "files": {}})
    assert finished_run_ids(sweep_dir, runs) == [runs[0].run_id]
    paths = write_tables(sweep_dir, runs)
    lines = open(paths["runs_csv"]).read().splitlines()
    assert len(lines) == 1 + len(runs)
    assert ",done,1,n1," in lines[1] and ",failed,3," in lines[2] and ",missing," in lines[3]
    md = open(paths["summary_md"]).read()
    assert "1 done, 1 failed, 2 not run" in md
    assert "100.0 (n=1)" in md
    # a second attempt replaces the first, whole
    write_run(sweep_dir, runs[1], {"status": "done", "attempts": 1, "files": {"report.json": json.dumps(report)}})
    assert sorted(os.listdir(os.path.join(sweep_dir, "runs", runs[1].run_id))) == ["outcome.json", "report.json"]
    with pytest.raises(ValueError, match="file named"):
        write_run(sweep_dir, runs[2], {"status": "done", "files": {"../evil": "x"}})


def test_progress_line_counts_and_estimates():
    p = Progress(total=10, skipped=2, done=3, failed=1, running=2, wall_s=[60.0, 120.0])
    assert p.left == 2
    assert p.estimate_s(parallel_runs=2) == 90.0 * 2
    assert p.line(2).startswith("3 done, 2 running, 1 failed, 2 left, 2 skipped")
