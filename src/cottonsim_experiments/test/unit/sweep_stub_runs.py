"""Run functions for the sweep engine's tests: no bringup, a report made from the run's parameters.

They live in a module of their own (not in the test file) because Ray's workers import them by name:
the test puts this folder on the workers' PYTHONPATH.
"""
import json
import os
import time

from cottonsim_experiments.sweep.route_runs import MasterPortTaken

MARKERS_ENV = "COTTONSIM_SWEEP_STUB_MARKERS"


def _report(run):
    noise = float(run.parameters.get("sim.gps.noise_std_m", 0.0))
    return {"complete": True, "cr_percent": 100.0, "ae_m": 0.05 + noise + 0.001 * run.seed, "plant_contacts": 0,
            "sim_duration_s": 10.0, "real_time_factor": 2.0}


def ok_run(run, cpus):
    time.sleep(0.5)
    return {"status": "done", "wall_s": 0.5, "cpus": cpus, "pid": os.getpid(),
            "files": {"report.json": json.dumps(_report(run)), "launch.log": f"stub run {run.run_id}\n"}}


def _first_attempt(run):
    marker = os.path.join(os.environ[MARKERS_ENV], run.run_id)
    if os.path.exists(marker):
        return False
    open(marker, "w").close()
    return True


def worker_dies_on_seed_1(run, cpus):
    """The worker process of seed 1's first attempt dies mid-run (as a killed or crashed worker would)."""
    if run.seed == 1 and _first_attempt(run):
        time.sleep(0.3)
        os._exit(1)
    return ok_run(run, cpus)


def master_port_taken_on_seed_0(run, cpus):
    if run.seed == 0 and _first_attempt(run):
        raise MasterPortTaken(f"run {run.run_id}: the master port was taken by another master")
    return ok_run(run, cpus)


def fails_on_seed_2(run, cpus):
    if run.seed == 2:
        raise RuntimeError("the bringup crashed")
    return ok_run(run, cpus)
