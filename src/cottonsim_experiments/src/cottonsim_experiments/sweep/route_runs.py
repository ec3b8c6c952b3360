"""One sweep run of a route experiment on whichever machine runs it: settings, bringup, small outputs.

:func:`execute_route_run` is what a Ray task calls. It works in a temporary folder of the machine
it runs on, starts the experiment's bringup on a master port of its own (see
:mod:`..reproduce.launcher`) with NUMBA_NUM_THREADS / OMP_NUM_THREADS set to the cores the run
reserved, and returns the small outputs (report.json, trajectory.csv, launch.log, sim.yaml) as
text, so a cluster needs no shared file system: the driver writes them.
"""
from __future__ import annotations

import json
import os
import platform
import shutil
import tempfile
import time
from typing import Any, Callable, Dict, Optional

from ..reproduce.launcher import LaunchSpec, run_launch
from ..reproduce.runs import (ROUTES, Workspace, deep_merge, offline_report_check, seed_overrides,
                              write_sim_config)
from .records import KEPT_DIR_KEY
from .spec import RunSpec

# What a run sends back to the driver (the bag stays on the worker: it is large).
RETURNED_FILES = ("report.json", "trajectory.csv", "launch.log", "sim.yaml")
# roslaunch prints this when it starts the master on the port it was given; a bringup that does
# not is talking to a master someone else started there.
_OWN_MASTER_LINE = "auto-starting new master"
_MASTER_URI_LINE = "ROS_MASTER_URI="
MAX_RETURNED_LOG_CHARS = 2_000_000


class MasterPortTaken(RuntimeError):
    """The run's master port was taken by another master between choosing and binding it (retried)."""


def _route_files(run: RunSpec, ws: Workspace):
    if run.experiment not in ROUTES:
        raise ValueError(f"experiment {run.experiment!r} is not a route experiment ({', '.join(ROUTES)})")
    route = ROUTES[run.experiment]
    waypoints = run.waypoints or os.path.join(ws.navigation, route["waypoints"])
    if not os.path.isfile(waypoints):
        raise ValueError(f"waypoints file {waypoints!r} does not exist")
    return route, os.path.abspath(waypoints), os.path.join(ws.experiments, route["sim_config"])


def run_sim_overrides(run: RunSpec) -> Dict[str, Any]:
    """The run's simulator overrides: the experiment's seed overrides with the grid point's merged in."""
    return deep_merge(seed_overrides(run.experiment, run.seed), run.sim_overrides)


def validate_route_run(run: RunSpec, ws: Optional[Workspace] = None) -> None:
    """ValueError naming the problem when a run's settings cannot start (checked in the driver, before any run)."""
    ws = ws or Workspace(results=tempfile.gettempdir())
    _, _, base_sim = _route_files(run, ws)
    with tempfile.TemporaryDirectory(prefix="cottonsim_sweep_check_") as tmp:
        write_sim_config(base_sim, run_sim_overrides(run), os.path.join(tmp, "sim.yaml"))
    for key, value in run.launch_args.items():
        if value is None or str(value) == "":
            raise ValueError(f"launch argument {key!r} needs a value")


def _master_watch():
    """An on_line callback that stops a bringup which joined a master it did not start."""
    state = {"own_master": False}

    def on_line(line: str) -> Optional[str]:
        if _OWN_MASTER_LINE in line:
            state["own_master"] = True
        elif _MASTER_URI_LINE in line and not state["own_master"]:
            return "the master port was taken by another master"
        return None
    return on_line


RouteWriter = Callable[[RunSpec, str, str], str]


def execute_route_run(run: RunSpec, cpus: int, keep_root: Optional[str] = None, launcher: Callable = run_launch,
                      route_writer: Optional[RouteWriter] = None, offline_check: bool = False) -> Dict[str, Any]:
    """Run one bringup of ``run`` here and return its outcome with its small outputs as text.

    ``keep_root``: a folder of this machine under which the whole run folder (bag, plot, offline
    check) is left and named in the outcome (``kept_dir``), for a driver on the same machine to move
    into place; default a temporary folder, removed after the outputs are read. ``route_writer(run,
    sim_yaml, out_dir)`` writes the run's own route file and returns its path (default: the run's
    waypoints or its experiment's route). ``offline_check``: a recorded bag is evaluated again
    offline (``evaluate_bag``) and the comparison returned as ``offline``. ``launcher`` runs the
    bringup (:func:`..reproduce.launcher.run_launch`; tests give another). Raises
    :class:`MasterPortTaken` for a retry.
    """
    os.environ["NUMBA_NUM_THREADS"] = os.environ["OMP_NUM_THREADS"] = str(int(cpus))
    if keep_root:
        os.makedirs(keep_root, exist_ok=True)
    work = tempfile.mkdtemp(prefix=f"cottonsim_{run.run_id}.", dir=keep_root or None)
    try:
        ws = Workspace(results=work)
        route, waypoints, base_sim = _route_files(run, ws)
        out_dir = os.path.join(work, run.run_id)
        sim_yaml = write_sim_config(base_sim, run_sim_overrides(run), os.path.join(out_dir, "sim.yaml"))
        if route_writer is not None:
            waypoints = route_writer(run, sim_yaml, out_dir)
        args = {"run_name": run.run_id, "results_dir": work, "sim_config": sim_yaml, "waypoints": waypoints,
                "real_time_factor": run.real_time_factor, "record_bag": str(bool(run.record_bag)).lower()}
        args.update({k: (str(v).lower() if isinstance(v, bool) else v) for k, v in run.launch_args.items()})
        spec = LaunchSpec("cottonsim_experiments", route["launch"], args, os.path.join(out_dir, "launch.log"),
                          run.wall_timeout_s, label=run.run_id)
        started = time.monotonic()
        result = launcher(spec, show_progress=False, on_line=_master_watch())
        if result.aborted_reason:
            raise MasterPortTaken(f"run {run.run_id}: {result.aborted_reason}")
        files = {}
        for name in RETURNED_FILES:
            path = os.path.join(out_dir, name)
            if os.path.isfile(path):
                with open(path, "r", encoding="utf-8", errors="replace") as fh:
                    text = fh.read()
                files[name] = text[-MAX_RETURNED_LOG_CHARS:] if name == "launch.log" else text
        has_report = "report.json" in files
        error = ""
        if not has_report:
            error = ("wall-clock limit reached" if result.timed_out
                     else f"no report (roslaunch exit {result.returncode}; see launch.log)")
        outcome = {"status": "done" if has_report else "failed", "error": error, "files": files,
                   "wall_s": time.monotonic() - started, "launch_returncode": result.returncode,
                   "timed_out": result.timed_out, "cpus": int(cpus), "node": platform.node(),
                   "load_average_1m": os.getloadavg()[0],
                   # a route written into the run folder is named relative to it (the folder moves)
                   "waypoints_file": (os.path.relpath(waypoints, out_dir)
                                      if waypoints.startswith(out_dir + os.sep) else waypoints)}
        bag = os.path.join(out_dir, "run.bag")
        if offline_check and has_report and os.path.isfile(bag):
            outcome["offline"] = offline_report_check(route["mode"], out_dir, waypoints, sim_yaml,
                                                      json.loads(files["report.json"]))
        if keep_root:
            outcome[KEPT_DIR_KEY] = out_dir
        return outcome
    finally:
        if not keep_root:
            shutil.rmtree(work, ignore_errors=True)
        elif os.path.isdir(work):
            # the run folder is the driver's to move; the attempt folder around it goes when it is empty
            for name in os.listdir(work):
                if name != run.run_id:
                    shutil.rmtree(os.path.join(work, name), ignore_errors=True)
