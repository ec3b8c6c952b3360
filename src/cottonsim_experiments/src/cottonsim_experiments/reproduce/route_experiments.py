"""The paper's route experiments as sweeps: the seeds of a route, and the row-spacing study.

Each is a list of runs built here in code and run by the sweep engine (:mod:`..sweep.engine`), the
same code path as ``reproduce sweep``: a local Ray cluster unless an address is given, one task per
bringup reserving its cores, retries of lost workers and taken master ports, ``--resume``, and
runs.csv / summary.md appended as runs finish. On a local cluster each run leaves its whole folder
(bag, trajectory plot, offline check) on this machine and the driver moves it into place; on a
remote cluster the runs return their small outputs and the bags stay on the workers.

  <route>/       seed_<s>/ (report.json, trajectory.png/.csv, run.bag, launch.log, sim.yaml, offline/,
                 outcome.json), runs.csv, summary.md, summary.json (the spread, read by results-doc)
  row_spacing/   runs/seed_<s>__row_spacing_m=<x>/ (one bringup each), runs/runs.csv, runs/summary.md,
                 seed_<s>/summary.json|md (the study per seed), summary.json|md (over the seeds)
"""
from __future__ import annotations

import dataclasses
import functools
import os
import shutil
from typing import Callable, Dict, List, Mapping, Optional, Sequence

from cottonsim_common.config.yaml_files import load_yaml_file

from cottonsim_experiments.recording.experiment import summary_line
from ..sweep.engine import EngineConfig, print_flush, run_sweep
from ..sweep.records import STATUS_DONE, read_outcome, read_run_report, run_dir
from ..sweep.route_runs import execute_route_run, validate_route_run
from ..sweep.spec import RunList, RunSpec, SweepSpec, run_id
from . import row_spacing as rs
from .launcher import run_launch
from .runs import (ROUTES, Workspace, machine_description, read_trajectory_y, widest_collision_radius_m,
                   write_json)
from .seeds import aggregate_reports

# What the reproduce commands run when no engine settings are given: a local cluster, and a run
# done before is run again (its folder replaced when the new outcome arrives) unless --resume.
DEFAULT_ENGINE = EngineConfig(replace_finished=True)
ATTEMPTS_DIR = ".attempts"      # under the run folders: where local runs leave their folders for the driver


def _run_on_engine(runs, sweep_dir: str, runs_dir: str, ws: Workspace, engine: EngineConfig, launcher: Callable,
                   log: Callable[[str], None], **run_options) -> None:
    """Run ``runs`` through the sweep engine; the runs' whole folders land in ``runs_dir`` on a local cluster."""
    keep_root = None if engine.address else os.path.join(runs_dir, ATTEMPTS_DIR)
    run_function = functools.partial(execute_route_run, keep_root=keep_root, launcher=launcher, **run_options)
    try:
        run_sweep(runs, sweep_dir, engine, run_function, validate=functools.partial(validate_route_run, ws=ws),
                  log=log, runs_dir=runs_dir)
    finally:
        if keep_root:
            shutil.rmtree(keep_root, ignore_errors=True)


def run_route(ws: Workspace, experiment: str, seeds: Sequence[int], real_time_factor: float = 0.0,
              record_bag: bool = True, extra_args: Optional[Mapping[str, object]] = None,
              wall_timeout_s: float = 5400.0, waypoints: Optional[str] = None, vision: bool = True,
              engine: EngineConfig = DEFAULT_ENGINE, launcher: Callable = run_launch,
              log: Callable[[str], None] = print_flush) -> Dict:
    """The GPS or map route once per seed (one sweep run each), then the spread in summary.json.

    Seeds: the GPS route seeds the simulator and the farm alike (a new farm per seed); the map route
    seeds the simulator only (sensor noise, solver order) and keeps the farm of its sim settings, the
    one the shipped SLAM map was drawn from (see :func:`.runs.seed_overrides`).

    With ``record_bag`` each run's bag is re-evaluated offline (``evaluate_bag``) and the summary
    says whether that reproduces the online report. ``waypoints`` replaces the paper's route file
    (quick checks on a short route). ``vision``: Cotton-Eye in the loop (the launch files' default,
    results/<experiment>/); False: the LiDAR + GPS run (results/<experiment>_no_vision/).
    """
    if experiment not in ROUTES:
        raise ValueError(f"experiment must be one of {sorted(ROUTES)}, got {experiment!r}")
    if not seeds:
        raise ValueError("seeds must name at least one seed")
    if waypoints is not None and not os.path.isfile(waypoints):
        raise ValueError(f"waypoints file {waypoints!r} does not exist")
    waypoints = os.path.abspath(waypoints or os.path.join(ws.navigation, ROUTES[experiment]["waypoints"]))
    name = experiment if vision else f"{experiment}_no_vision"
    out_dir = os.path.join(ws.results, name)
    machine = machine_description()
    fixed = {"launch.vision": bool(vision)}
    fixed.update({f"launch.{k}": v for k, v in (extra_args or {}).items()})
    spec = SweepSpec(name=name, experiment=experiment, seeds=tuple(int(s) for s in seeds), fixed=fixed,
                     waypoints=waypoints, real_time_factor=float(real_time_factor), record_bag=bool(record_bag),
                     wall_timeout_s=float(wall_timeout_s))
    _run_on_engine(spec, out_dir, out_dir, ws, engine, launcher, log, offline_check=bool(record_bag))
    runs = []
    for run in spec.runs():
        outcome = read_outcome(out_dir, run.run_id) or {}
        report = read_run_report(out_dir, run.run_id) if outcome.get("status") == STATUS_DONE else None
        entry = {"seed": run.seed, "run_dir": run_dir(out_dir, run.run_id), "report": report,
                 "launch_returncode": outcome.get("launch_returncode"),
                 "launch_timed_out": bool(outcome.get("timed_out", False)), "launch_wall_s": outcome.get("wall_s"),
                 "attempts": outcome.get("attempts"), "node": outcome.get("node")}
        if "offline" in outcome:
            entry["offline"] = outcome["offline"]
        runs.append(entry)
        log(f"  seed {run.seed}: " + (summary_line(report) if report else
                                      f"no report (see {entry['run_dir']}/launch.log)"))
    reports = [r["report"] for r in runs if r["report"] is not None]
    summary = {"experiment": experiment, "mode": ROUTES[experiment]["mode"], "vision": bool(vision),
               "seeds": list(spec.seeds), "machine": machine, "waypoints_file": waypoints,
               "runs_with_report": len(reports), "runs": runs, "spread": aggregate_reports(reports),
               "all_complete": len(reports) == len(spec.seeds) and all(r.get("complete", False) for r in reports)}
    write_json(os.path.join(out_dir, "summary.json"), summary)
    return summary


def farm_of_run(sim_yaml: str):
    """The FarmConfig of a run's sim.yaml (its farm section over the defaults)."""
    from cottonsim_world.farm.config import FarmConfig

    return FarmConfig.from_dict(load_yaml_file(sim_yaml, default={}).get("farm") or {})


def write_gps_route(sim_yaml: str, points_xy_m, path: str, comment: str) -> str:
    """World points [m] as a GPS waypoint file ('lat lon' lines) at ``path``, through the geodetic reference of
    the run's simulator settings, so the route matches the simulated farm; returns the path."""
    from cottonsim_world.config_io import simulator_config_from_dict
    from cottonsim_world.geodesy import HectorGeodesy

    settings = load_yaml_file(sim_yaml, default={})
    geodesy = HectorGeodesy(*simulator_config_from_dict(settings).geodesy_reference)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(f"# {comment}\n")
        for x, y in points_xy_m:
            lat, lon, _ = geodesy.world_to_geodetic(x, y, 0.0)
            fh.write(f"{float(lat):.14f} {float(lon):.14f}\n")
    return path


def write_lane_route(run: RunSpec, sim_yaml: str, out_dir: str) -> str:
    """A row-spacing run's route: entry, middle and exit of lane 1 of the run's farm, as GPS waypoints.

    Called where the run runs (a Ray worker): the farm comes from the run's sim.yaml, the
    geodetic reference from the simulator's settings, so the route matches the simulated farm.
    """
    farm = farm_of_run(sim_yaml)
    return write_gps_route(sim_yaml, rs.attempt_route_world(farm), os.path.join(out_dir, "route_gps.txt"),
                           f"lane 1 (between rows 0 and 1) at {farm.row_spacing_m:.2f} m row spacing: "
                           "entry, middle, exit")


def row_spacing_runs(config: rs.RowSpacingStudyConfig, seeds: Sequence[int], real_time_factor: float,
                     wall_timeout_s: float) -> RunList:
    """One run per seed and spacing: the attempt's farm, the navigator stopping at its first failure, no cameras
    (a traversability study of the LiDAR costmap)."""
    runs: List[RunSpec] = []
    for seed in seeds:
        seeded = dataclasses.replace(config, seed=int(seed))
        for spacing in seeded.spacings_m:
            parameters = {"row_spacing_m": spacing}
            runs.append(RunSpec(run_id=run_id(int(seed), parameters), experiment="gps_route", seed=int(seed),
                                sim_overrides={"farm": rs.attempt_farm_settings(seeded, spacing)},
                                launch_args={"on_failure": "stop", "goal_timeout_s": seeded.goal_timeout_s,
                                             "vision": False},
                                parameters=parameters, real_time_factor=float(real_time_factor),
                                record_bag=False, wall_timeout_s=float(wall_timeout_s)))
    return RunList(name="row_spacing", run_list=tuple(runs))


def run_row_spacing(ws: Workspace, config: rs.RowSpacingStudyConfig = rs.RowSpacingStudyConfig(),
                    real_time_factor: float = 0.0, wall_timeout_s: float = 1200.0,
                    seeds: Optional[Sequence[int]] = None, engine: EngineConfig = DEFAULT_ENGINE,
                    launcher: Callable = run_launch, log: Callable[[str], None] = print_flush) -> Dict:
    """The paper's Fig. 3a study: one GPS-navigation bringup per spacing and seed (see :mod:`.row_spacing`).

    Runs every (seed, spacing) as one sweep into row_spacing/runs/, then writes
    row_spacing/seed_<s>/{summary.json, summary.md} per seed (default: ``config.seed`` alone) and
    row_spacing/{summary.json, summary.md} over the seeds.
    """
    from cottonsim_world.farm.config import FarmConfig

    out_dir = os.path.join(ws.results, "row_spacing")
    runs_dir = os.path.join(out_dir, "runs")
    machine = machine_description()
    seeds = [int(s) for s in (seeds or [config.seed])]
    runs = row_spacing_runs(config, seeds, real_time_factor, wall_timeout_s)
    _run_on_engine(runs, runs_dir, runs_dir, ws, engine, launcher, log, route_writer=write_lane_route)
    per_seed = []
    for seed in seeds:
        seeded = dataclasses.replace(config, seed=seed)
        outcomes, farm = [], None
        for run in (r for r in runs.runs() if r.seed == seed):
            spacing = run.parameters["row_spacing_m"]
            farm = FarmConfig.from_dict(run.sim_overrides["farm"])
            folder = run_dir(runs_dir, run.run_id)
            ys = read_trajectory_y(os.path.join(folder, "trajectory.csv"))
            error = "wall-clock limit reached" if (read_outcome(runs_dir, run.run_id) or {}).get("timed_out") else ""
            outcome = rs.outcome_from_report(spacing, farm.plant_width_m, read_run_report(runs_dir, run.run_id),
                                             error, None if ys is None else rs.lane_progress_m(ys, farm))
            outcomes.append(outcome)
            log(f"  row spacing {spacing:.2f} m, seed {seed}: "
                + ("traversed" if outcome.traversed else "NOT traversed: " + outcome.reason))
        robot_width = farm.robot_width_m if farm is not None else float("nan")
        summary = rs.study_summary(seeded, outcomes, robot_width, widest_collision_radius_m(farm))
        seed_dir = os.path.join(out_dir, f"seed_{seed}")
        write_json(os.path.join(seed_dir, "summary.json"), summary)
        with open(os.path.join(seed_dir, "summary.md"), "w", encoding="utf-8") as fh:
            fh.write(rs.summary_markdown(summary) + "\n")
        per_seed.append(summary)
    summary = dict(rs.seeds_summary(per_seed), machine=machine)
    write_json(os.path.join(out_dir, "summary.json"), summary)
    with open(os.path.join(out_dir, "summary.md"), "w", encoding="utf-8") as fh:
        fh.write(rs.seeds_markdown(summary) + "\n")
    return summary
