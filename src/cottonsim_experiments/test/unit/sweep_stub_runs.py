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


def stub_launch(spec, show_progress=False, on_line=None, reports=None):
    """Stands in for run_launch in the reproduce experiments' tests: no bringup; writes the report given
    for the run (``reports``: run name -> report, None for a run that ends without one), the launch
    arguments (launch_args.json, for the test to read) and a plot, where the launch would have."""
    from cottonsim_experiments.reproduce.launcher import LaunchResult

    run_dir = os.path.join(spec.args["results_dir"], spec.args["run_name"])
    os.makedirs(run_dir, exist_ok=True)
    with open(os.path.join(run_dir, "launch_args.json"), "w") as fh:
        json.dump({k: str(v) for k, v in spec.args.items()}, fh)
    with open(os.path.join(run_dir, "trajectory.png"), "wb") as fh:
        fh.write(b"\x89PNG stub")
    with open(spec.log_path, "w") as fh:
        fh.write(f"stub launch of {spec.launch_file}\n")
    report = (reports or {}).get(spec.args["run_name"])
    if report is not None:
        with open(os.path.join(run_dir, "report.json"), "w") as fh:
            json.dump(report, fh)
    return LaunchResult(0, False, 0.1, spec.log_path)
