"""The sweep engine on a local Ray cluster of 2 CPUs, with stub runs (no bringup): every run present once,
a dead worker's run retried, a taken master port retried, a failing run recorded, --resume."""
import csv
import json
import os

import pytest

import ray  # (a pinned requirement: missing is a failure, not a skip)

from cottonsim_experiments.sweep.engine import EngineConfig, run_sweep  # noqa: E402
from cottonsim_experiments.sweep.spec import SweepConfigError, parse_sweep  # noqa: E402


def _spec(name, seeds=(0, 1, 2)):
    return parse_sweep({"name": name, "experiment": "gps_route", "seeds": list(seeds),
                        "grid": {"sim.gps.noise_std_m": [0.0, 0.1]}})


def _rows(sweep_dir):
    with open(os.path.join(sweep_dir, "runs.csv")) as fh:
        return list(csv.DictReader(fh))


def _config(**kw):
    return EngineConfig(cpus_per_run=1, progress_interval_s=1.0, **kw)


def test_every_run_is_written_once_with_its_report(ray_cluster, tmp_path):
    import sweep_stub_runs
    lines = []
    result = run_sweep(_spec("ok"), str(tmp_path), _config(), sweep_stub_runs.ok_run, log=lines.append)
    rows = _rows(str(tmp_path))
    assert len(rows) == 6 and len({r["run_id"] for r in rows}) == 6
    assert all(r["status"] == "done" and r["attempts"] == "1" and r["cr_percent"] == "100" for r in rows)
    assert result["counts"]["done"] == 6 and result["counts"]["failed"] == 0
    ae = {r["run_id"]: float(r["ae_m"]) for r in rows}
    assert ae["seed_2__gps.noise_std_m=0.1"] == pytest.approx(0.152)
    assert any("6 done, 0 running, 0 failed, 0 left" in line for line in lines)
    assert "| 0.1 | 3/3 |" in open(os.path.join(str(tmp_path), "summary.md")).read()


def test_a_worker_that_dies_mid_run_is_retried_and_its_run_is_present_once(ray_cluster, tmp_path):
    import sweep_stub_runs
    run_sweep(_spec("dies"), str(tmp_path), _config(), sweep_stub_runs.worker_dies_on_seed_1, log=lambda s: None)
    rows = _rows(str(tmp_path))
    assert len(rows) == 6 and all(r["status"] == "done" for r in rows)
    attempts = {r["run_id"]: r["attempts"] for r in rows}
    assert attempts["seed_1__gps.noise_std_m=0"] == "2" and attempts["seed_1__gps.noise_std_m=0.1"] == "2"
    assert attempts["seed_0__gps.noise_std_m=0"] == "1"


def test_a_taken_master_port_is_retried_and_other_failures_are_recorded_not_retried(ray_cluster, tmp_path):
    import sweep_stub_runs
    run_sweep(_spec("port"), str(tmp_path / "port"), _config(), sweep_stub_runs.master_port_taken_on_seed_0,
              log=lambda s: None)
    rows = _rows(str(tmp_path / "port"))
    assert all(r["status"] == "done" for r in rows)
    assert {r["attempts"] for r in rows if r["seed"] == "0"} == {"2"}
    run_sweep(_spec("fails"), str(tmp_path / "fails"), _config(), sweep_stub_runs.fails_on_seed_2,
              log=lambda s: None)
    rows = _rows(str(tmp_path / "fails"))
    failed = [r for r in rows if r["status"] == "failed"]
    assert len(failed) == 2 and all(r["seed"] == "2" and r["attempts"] == "1" for r in failed)
    assert all("the bringup crashed" in r["error"] for r in failed)


def test_resume_skips_finished_runs_and_a_second_sweep_never_overwrites_them(ray_cluster, tmp_path):
    import sweep_stub_runs
    sweep_dir = str(tmp_path)
    run_sweep(_spec("resume", seeds=(0,)), sweep_dir, _config(), sweep_stub_runs.ok_run, log=lambda s: None)
    outcome = os.path.join(sweep_dir, "runs", "seed_0__gps.noise_std_m=0", "outcome.json")
    before = json.load(open(outcome))
    with pytest.raises(SweepConfigError, match="--resume"):
        run_sweep(_spec("resume", seeds=(0, 1)), sweep_dir, _config(), sweep_stub_runs.ok_run, log=lambda s: None)
    result = run_sweep(_spec("resume", seeds=(0, 1)), sweep_dir, _config(resume=True), sweep_stub_runs.ok_run,
                       log=lambda s: None)
    assert result["counts"]["skipped"] == 2 and result["counts"]["done"] == 2
    assert json.load(open(outcome)) == before
    assert len(_rows(sweep_dir)) == 4
