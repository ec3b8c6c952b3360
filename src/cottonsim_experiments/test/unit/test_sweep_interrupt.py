"""Ctrl-C during a sweep: `reproduce sweep` (the real command, its own local Ray cluster of 2 CPUs) with a
stand-in `roslaunch` first on PATH; SIGINT to the driver stops every running bringup with SIGINT, leaves no
child process, and keeps the finished run in runs.csv."""
import csv
import json
import os
import signal
import subprocess
import sys
import time

import pytest

import ray  # noqa: F401  (a pinned requirement: missing is a failure, not a skip)

# A stand-in for roslaunch (`roslaunch -p PORT PKG FILE k:=v ...`): it says it started its own master,
# then seed 0 writes its report and ends; every other run starts a long child (a "node") in its
# process group, notes both pids, and on SIGINT notes that and stops the child: a clean stop.
FAKE_ROSLAUNCH = r'''#!/usr/bin/env python3
import json, os, signal, subprocess, sys, time
args = dict(a.split(":=", 1) for a in sys.argv[1:] if ":=" in a)
run_dir = os.path.join(args["results_dir"], args["run_name"])
os.makedirs(run_dir, exist_ok=True)
markers = os.environ["FAKE_ROSLAUNCH_MARKERS"]
print("... logging to x\nauto-starting new master", flush=True)
if args["run_name"] == "seed_0":
    with open(os.path.join(run_dir, "report.json"), "w") as fh:
        json.dump({"complete": True, "cr_percent": 100.0, "ae_m": 0.05, "plant_contacts": 0}, fh)
    sys.exit(0)
node = subprocess.Popen(["sleep", "600"])
def stop(*_):
    open(os.path.join(markers, args["run_name"] + ".sigint"), "w").close()
    node.terminate()
    node.wait()
    sys.exit(0)
signal.signal(signal.SIGINT, stop)
with open(os.path.join(markers, args["run_name"] + ".pids"), "w") as fh:
    fh.write(f"{os.getpid()} {node.pid}")
while True:
    time.sleep(0.2)
'''
LONG_RUNS = ("seed_1", "seed_2")


def _alive(pid: int) -> bool:
    """The process exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/status") as fh:
            return not any(line.startswith("State:") and "Z" in line.split()[1] for line in fh)
    except OSError:
        return False


def _wait_for(predicate, limit_s: float, what: str, proc) -> None:
    deadline = time.monotonic() + limit_s
    while not predicate():
        if proc.poll() is not None:
            pytest.fail(f"the sweep ended before {what}:\n" + proc.stdout.read()[-3000:])
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"no {what} within {limit_s:.0f} s:\n" + proc.stdout.read()[-3000:])
        time.sleep(0.5)


def test_sigint_stops_every_bringup_cleanly_and_keeps_the_finished_runs(tmp_path):
    bin_dir, markers, results = tmp_path / "bin", tmp_path / "markers", tmp_path / "results"
    bin_dir.mkdir()
    markers.mkdir()
    fake = bin_dir / "roslaunch"
    fake.write_text(FAKE_ROSLAUNCH)
    fake.chmod(0o755)
    sweep = tmp_path / "interrupt.yaml"
    sweep.write_text("name: interrupt\nexperiment: gps_route\nseeds: [0, 1, 2]\nfixed:\n  launch.vision: false\n")
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", FAKE_ROSLAUNCH_MARKERS=str(markers))
    cmd = [sys.executable, "-c", "import sys; from cottonsim_experiments.reproduce.cli import main; sys.exit(main())",
           "sweep", "--config", str(sweep), "--results", str(results), "--local-cpus", "2", "--cpus-per-run", "1"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    pid_files = [markers / f"{name}.pids" for name in LONG_RUNS]
    try:
        # seed 0 ends at once; seeds 1 and 2 then both run (one CPU each) until stopped
        _wait_for(lambda: all(p.exists() for p in pid_files), 300.0, "two long bringups running", proc)
        pids = [int(pid) for p in pid_files for pid in p.read_text().split()]
        assert all(_alive(pid) for pid in pids)
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=240)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, out[-3000:]
    assert "interrupted: stopping 2 runs" in out, out[-3000:]
    assert [pid for pid in pids if _alive(pid)] == [], "processes of a bringup survived the sweep"
    for name in LONG_RUNS:        # each bringup got SIGINT (unblocked in the child of a Ray worker) and stopped
        assert (markers / f"{name}.sigint").exists(), name
    sweep_dir = results / "sweeps" / "interrupt"
    rows = {r["run_id"]: r for r in csv.DictReader(open(sweep_dir / "runs.csv"))}
    assert rows["seed_0"]["status"] == "done" and rows["seed_0"]["cr_percent"] == "100"
    assert rows["seed_1"]["status"] == rows["seed_2"]["status"] == "missing"
    assert json.load(open(sweep_dir / "runs" / "seed_0" / "outcome.json"))["status"] == "done"
    assert sorted(os.listdir(sweep_dir / "runs")) == ["seed_0"]
