"""Sweep files: parsing, refusals naming the key, expansion into runs with stable ids; the run records."""
import json
import os

import pytest

from cottonsim_experiments.sweep.records import Progress, finished_run_ids, write_run
from cottonsim_experiments.sweep.tables import SweepTables, write_tables
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
    runs_dir = os.path.join(sweep_dir, "runs")
    report = {"complete": True, "cr_percent": 100.0, "ae_m": 0.05, "plant_contacts": 0}
    write_run(runs_dir, runs[0], {"status": "done", "attempts": 1, "node": "n1",
                                  "files": {"report.json": json.dumps(report), "launch.log": "ok\n"}})
    write_run(runs_dir, runs[1], {"status": "failed", "attempts": 3, "error": "no report", "files": {}})
    assert finished_run_ids(runs_dir, runs) == [runs[0].run_id]
    paths = write_tables(sweep_dir, runs)
    lines = open(paths["runs_csv"]).read().splitlines()
    assert len(lines) == 1 + len(runs)
    assert ",done,1,n1," in lines[1] and ",failed,3," in lines[2] and ",missing," in lines[3]
    md = open(paths["summary_md"]).read()
    assert "1 done, 1 failed, 2 not run" in md
    assert "100.0 (n=1)" in md
    # a second attempt replaces the first, whole
    write_run(runs_dir, runs[1], {"status": "done", "attempts": 1, "files": {"report.json": json.dumps(report)}})
    assert sorted(os.listdir(os.path.join(runs_dir, runs[1].run_id))) == ["outcome.json", "report.json"]
    with pytest.raises(ValueError, match="file named"):
        write_run(runs_dir, runs[2], {"status": "done", "files": {"../evil": "x"}})
    assert sorted(os.listdir(runs_dir)) == sorted(r.run_id for r in runs[:2])       # no staging folder left
    mask = os.umask(0o022)
    os.umask(mask)
    assert os.stat(os.path.join(runs_dir, runs[0].run_id)).st_mode & 0o777 == 0o777 & ~mask


def test_a_run_folder_left_on_the_drivers_disk_is_moved_into_the_run_folder(tmp_path):
    run = _sweep().runs()[0]
    kept = tmp_path / "attempts" / "a1"
    (kept / "offline").mkdir(parents=True)
    (kept / "run.bag").write_bytes(b"\x00bag")
    (kept / "offline" / "report.json").write_text("{}")
    (kept / "report.json").write_text("stale")              # the returned text wins
    final = write_run(str(tmp_path / "runs"), run, {"status": "done", "kept_dir": str(kept),
                                                     "files": {"report.json": "{\"cr_percent\": 100}"}})
    assert sorted(os.listdir(final)) == ["offline", "outcome.json", "report.json", "run.bag"]
    assert open(os.path.join(final, "run.bag"), "rb").read() == b"\x00bag"
    assert json.load(open(os.path.join(final, "report.json"))) == {"cr_percent": 100}
    outcome = json.load(open(os.path.join(final, "outcome.json")))
    assert "kept_dir" not in outcome and "run.bag" in outcome["files"]
    assert not kept.exists()
    # a folder that is not on this machine (a remote worker's) is ignored
    final = write_run(str(tmp_path / "runs"), run, {"status": "done", "kept_dir": "/nonexistent/x", "files": {}})
    assert sorted(os.listdir(final)) == ["outcome.json"]


class _Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_tables_append_one_row_per_outcome_and_write_the_summary_every_k_runs_or_seconds(tmp_path):
    runs = _sweep(seeds=list(range(7))).runs()
    clock = _Clock()
    tables = SweepTables(str(tmp_path), runs, summary_every_runs=3, summary_every_s=100.0, clock=clock)
    tables.start()
    csv_path = tmp_path / "runs.csv"
    before = csv_path.read_text()
    assert before.count("\n") == 1 and not (tmp_path / "summary.md").exists()
    order = [3, 0, 5, 1]
    for k, i in enumerate(order):
        tables.add(runs[i], {"status": "done", "attempts": 1}, {"cr_percent": 100.0, "ae_m": 0.01 * i})
        text = csv_path.read_text()
        assert text.startswith(before) and text.count("\n") == k + 2          # appended, never rewritten
        before = text
    assert [line.split(",")[0] for line in before.splitlines()[1:]] == [runs[i].run_id for i in order]
    assert tables.summaries_written == 1                                     # after the 3rd outcome
    assert "3 done, 0 failed, 4 not run" in (tmp_path / "summary.md").read_text()
    clock.t = 150.0                                                          # the timer: one more outcome
    tables.add(runs[2], {"status": "failed", "attempts": 1, "error": "no report"}, None)
    assert tables.summaries_written == 2
    assert "4 done, 1 failed, 2 not run" in (tmp_path / "summary.md").read_text()
    tables.finish()                                                          # run order, missing ones listed
    rows = csv_path.read_text().splitlines()[1:]
    assert [r.split(",")[0] for r in rows] == [r.run_id for r in runs]
    assert ",missing," in rows[4] and ",failed," in rows[2]
    with pytest.raises(ValueError, match="summary_every_runs"):
        SweepTables(str(tmp_path), runs, summary_every_runs=0)


def test_tables_start_with_the_runs_finished_before(tmp_path):
    runs = _sweep().runs()
    write_run(str(tmp_path / "runs"), runs[1], {"status": "done", "attempts": 2,
                                                "files": {"report.json": json.dumps({"ae_m": 0.07})}})
    tables = SweepTables(str(tmp_path), runs)
    tables.start([runs[1].run_id])
    rows = (tmp_path / "runs.csv").read_text().splitlines()
    assert len(rows) == 2 and rows[1].startswith(runs[1].run_id + ",1,done,2,") and ",0.07," in rows[1]


def test_progress_line_counts_and_estimates():
    p = Progress(total=10, skipped=2, done=3, failed=1, running=2, wall_s=[60.0, 120.0])
    assert p.left == 2
    assert p.estimate_s(parallel_runs=2) == 90.0 * 2
    assert p.line(2).startswith("3 done, 2 running, 1 failed, 2 left, 2 skipped")
