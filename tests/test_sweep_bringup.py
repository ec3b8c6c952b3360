"""`reproduce sweep` end to end: one real short bringup (3 GPS waypoints, no cameras) as a Ray task on a
local cluster of 2 CPUs, its report returned to the driver and written into the sweep's tables."""
import csv
import json
import os
import subprocess

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROUTE = os.path.join(ROOT, "src", "cottonsim_navigation", "config", "waypoints", "gps_test_3.txt")


def test_a_sweep_of_one_short_bringup_writes_its_run_and_tables(tmp_path):
    sweep = tmp_path / "short.yaml"
    sweep.write_text(f"name: short\nexperiment: gps_route\nseeds: [0]\nwaypoints: {ROUTE}\n"
                     "fixed:\n  launch.vision: false\nwall_timeout_s: 900\n")
    results = tmp_path / "results"
    proc = subprocess.run(["rosrun", "cottonsim_experiments", "reproduce", "sweep", "--config", str(sweep),
                           "--results", str(results), "--local-cpus", "2", "--cpus-per-run", "2"],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=1200)
    assert proc.returncode == 0, proc.stdout[-3000:]
    sweep_dir = results / "sweeps" / "short"
    rows = list(csv.DictReader(open(sweep_dir / "runs.csv")))
    assert len(rows) == 1 and rows[0]["run_id"] == "seed_0" and rows[0]["status"] == "done", rows
    assert float(rows[0]["cr_percent"]) == 100.0 and rows[0]["plant_contacts"] == "0"
    run_dir = sweep_dir / "runs" / "seed_0"
    assert {"report.json", "launch.log", "sim.yaml", "outcome.json"} <= set(os.listdir(run_dir))
    outcome = json.load(open(run_dir / "outcome.json"))
    assert outcome["attempts"] == 1 and outcome["node"] and outcome["cpus"] == 2
    assert "auto-starting new master" in (run_dir / "launch.log").read_text()
    assert "1 done, 0 running, 0 failed, 0 left" in proc.stdout
