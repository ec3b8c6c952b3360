"""``reproduce harvest``: the harvest on the GPS route, one run per seed, judged against the simulator's truth.

Each seed is one bringup of gps_navigation.launch with ``harvest:=true`` through the sweep engine (as
``reproduce gps-route``), on the seed's farm, driving the harvest route (harvest_run.route: by default
row 1 from both its lanes, lane 1 north then lane 2 south; ``lanes='all'``: every lane). Per run the
folder holds report.json, harvest.json (the harvest recorder), sim.yaml, route_gps.txt, the bag when
recorded, and from the evaluation (harvest_run.evaluation) harvest_outcomes.json, harvest_figures.json
and harvest_field.png. Then results/harvest[_ground_truth]/summary.json and summary.md: the figures
per seed and pooled over the seeds, beside the published anchors (harvest.metrics.ANCHORS).
"""
from __future__ import annotations

import functools
import json
import os
from typing import Callable, Dict, List, Optional, Sequence

from ..harvest_run.evaluation import HarvestEvaluationError, evaluate_run, harvest_module, pooled_figures
from ..harvest_run.route import LANES_ROW, TARGET_SOURCES, harvest_lanes, serpentine_route
from ..sweep.engine import EngineConfig, print_flush
from ..sweep.records import STATUS_DONE, read_outcome, run_dir
from ..sweep.spec import RunList, RunSpec, run_id
from .launcher import run_launch
from .packages import package_path
from .route_experiments import DEFAULT_ENGINE, _run_on_engine, farm_of_run, write_gps_route
from .runs import Workspace, machine_description, write_json

# (figure key, label, format) of summary.md and the results page; a dotted key reads a nested figure
FIGURE_ROWS = (("open_bolls", "open bolls on the rows beside the route", "{:.0f}"),
               ("reachable", "reachable from the route", "{:.0f}"),
               ("detected", "detected (a target within 5 cm)", "{:.0f}"),
               ("attempted", "attempted", "{:.0f}"),
               ("picked", "picked (captured)", "{:.0f}"),
               ("in_bin", "in the bin", "{:.0f}"),
               ("harvest_success_percent", "harvest success [% of reachable]", "{:.1f}"),
               ("field_harvest_percent", "field harvest [% of open]", "{:.1f}"),
               ("cycle_time_s.median", "cycle time per boll, median [s]", "{:.1f}"),
               ("cycle_time_s.p95", "cycle time per boll, p95 [s]", "{:.1f}"),
               ("bolls_per_hour", "bolls per hour of field time", "{:.0f}"),
               ("bolls_per_hour_picking", "bolls per hour of picking", "{:.0f}"),
               ("localization_error_m.median", "localisation error, median [mm]", "mm"),
               ("localization_error_m.p95", "localisation error, p95 [mm]", "mm"),
               ("arm_stem_contacts", "arm-stem contacts", "{:.0f}"),
               ("arm_leaf_contacts", "arm-leaf contacts", "{:.0f}"),
               ("base_plant_contacts", "base-plant contacts", "{:.0f}"),
               ("route_time_s", "route time (sim) [min]", "min"),
               ("real_time_factor", "real-time factor", "{:.2f}"))


def write_harvest_route(run: RunSpec, sim_yaml: str, out_dir: str, lanes="row", row: int = 1) -> str:
    """The run's harvest route (harvest_run.route) on the run's farm, as GPS waypoints in out_dir/route_gps.txt."""
    farm = farm_of_run(sim_yaml)
    chosen = harvest_lanes(farm, lanes, row)
    route = serpentine_route(farm, chosen)
    return write_gps_route(sim_yaml, [(w.x_m, w.y_m) for w in route], os.path.join(out_dir, "route_gps.txt"),
                           f"harvest route over lanes {chosen}: entry, middle, exit of each, a serpentine")


def harvest_runs(seeds: Sequence[int], targets: str, vision: bool, real_time_factor: float, record_bag: bool,
                 wall_timeout_s: float) -> RunList:
    """One GPS-route run per seed with the harvest on (its own farm per seed)."""
    if targets not in TARGET_SOURCES:
        raise ValueError(f"targets must be one of {TARGET_SOURCES}, got {targets!r}")
    if targets == "detections" and not vision:
        raise ValueError("targets 'detections' need the cameras and the networks: vision must be on")
    runs = [RunSpec(run_id=run_id(int(s), {}), experiment="gps_route", seed=int(s), sim_overrides={},
                    launch_args={"harvest": True, "harvest_targets": targets, "vision": bool(vision)},
                    parameters={}, real_time_factor=float(real_time_factor), record_bag=bool(record_bag),
                    wall_timeout_s=float(wall_timeout_s)) for s in seeds]
    return RunList(name="harvest", run_list=tuple(runs))


def figure_value(figures: Optional[Dict], key: str):
    """A figure by its (dotted) key, None when absent."""
    value = figures
    for part in key.split("."):
        value = value.get(part) if isinstance(value, dict) else None
    return value


def _cell(value, fmt: str) -> str:
    if value is None:
        return "-"
    if fmt == "mm":
        return f"{1000.0 * value:.1f}"
    if fmt == "min":
        return f"{value / 60.0:.2f}"
    return fmt.format(value)


def figures_table(columns: Dict[str, Optional[Dict]]) -> List[str]:
    """A markdown table: one row per figure (FIGURE_ROWS), one column per named figure set."""
    lines = ["| figure | " + " | ".join(columns) + " |", "|---|" + "---|" * len(columns)]
    for key, label, fmt in FIGURE_ROWS:
        lines.append(f"| {label} | " + " | ".join(_cell(figure_value(f, key), fmt) for f in columns.values()) + " |")
    return lines


def anchors_lines(anchors: Dict[str, Dict]) -> List[str]:
    """The published anchors (harvest.metrics.ANCHORS) as a list."""
    return [f"- {name}: " + "; ".join(f"{k} {v}" for k, v in figures.items()) for name, figures in anchors.items()]


def summary_markdown(summary: Dict) -> str:
    """summary.md: the figures per seed and pooled, the anchors, the funnel."""
    columns = {f"seed {r['seed']}": r.get("figures") for r in summary["runs"]}
    columns["pooled"] = summary.get("pooled")
    lines = [f"# Harvest: lanes {summary['lanes']}, targets from {summary['targets']}", ""]
    lines += figures_table(columns) + ["", "Anchors (real robots):", ""] + anchors_lines(summary.get("anchors", {}))
    funnel = (summary.get("pooled") or {}).get("funnel") or []
    if funnel:
        lines += ["", "Funnel (pooled): " + " -> ".join(
            f"{s['stage']} {s['count']}" + ("" if s["percent_of_previous"] is None else f" ({s['percent_of_previous']:.0f} %)")
            for s in funnel)]
    for r in summary["runs"]:
        if r.get("error"):
            lines.append(f"- seed {r['seed']}: {r['error']}")
    return "\n".join(lines) + "\n"


def run_harvest(ws: Workspace, seeds: Sequence[int], lanes="row", row: int = 1, targets: str = "detections",
                vision: Optional[bool] = None, real_time_factor: float = 0.0, record_bag: bool = True,
                wall_timeout_s: float = 5400.0, engine: EngineConfig = DEFAULT_ENGINE,
                launcher: Callable = run_launch, log: Callable[[str], None] = print_flush) -> Dict:
    """Run and judge the harvest per seed; writes results/harvest[_ground_truth]/summary.json|md (module docstring).

    ``vision`` defaults to on for the networks' detections and off for ground-truth targets (no camera
    is needed then). The figures need cottonsim_experiments.harvest (metrics, reachability, field_plot);
    checked before any run starts.
    """
    if not seeds:
        raise ValueError("seeds must name at least one seed")
    vision = (targets == "detections") if vision is None else bool(vision)
    metrics = harvest_module("metrics")
    harvest_module("reachability")
    if lanes != LANES_ROW and lanes != "all":
        raise ValueError(f"lanes must be 'row' or 'all', got {lanes!r}")
    name = "harvest" if targets == "detections" else f"harvest_{targets}"
    out_dir = os.path.join(ws.results, name)
    runs = harvest_runs(seeds, targets, vision, real_time_factor, record_bag, wall_timeout_s)
    _run_on_engine(runs, out_dir, out_dir, ws, engine, launcher, log,
                   route_writer=functools.partial(write_harvest_route, lanes=lanes, row=row))
    with open(os.path.join(package_path("cottonsim_description"), "urdf", "cottonsim_robot.urdf"), "r",
              encoding="utf-8") as fh:
        urdf_xml = fh.read()
    entries, judged = [], []
    for run in runs.runs():
        folder = run_dir(out_dir, run.run_id)
        entry = {"seed": run.seed, "run_dir": folder, "figures": None, "error": ""}
        outcome = read_outcome(out_dir, run.run_id) or {}
        if outcome.get("status") != STATUS_DONE:
            entry["error"] = f"no report ({outcome.get('error') or 'the run failed'}; see {folder}/launch.log)"
        else:
            farm = farm_of_run(os.path.join(folder, "sim.yaml"))
            entry["lanes"] = harvest_lanes(farm, lanes, row)
            try:
                entry["figures"] = evaluate_run(folder, entry["lanes"], urdf_xml)
                with open(os.path.join(folder, "harvest_outcomes.json"), "r", encoding="utf-8") as fh:
                    judged.append(json.load(fh))
            except HarvestEvaluationError as exc:
                entry["error"] = str(exc)
        log(f"  seed {run.seed}: " + (entry["error"] or f"{entry['figures']['in_bin']} bolls in the bin of "
                                      f"{entry['figures']['reachable']} reachable"))
        entries.append(entry)
    summary = {"experiment": "harvest", "lanes": lanes if lanes == "all" else f"row {row} from both lanes",
               "targets": targets, "vision": vision, "seeds": [int(s) for s in seeds],
               "machine": machine_description(), "runs": entries,
               "pooled": pooled_figures(judged, metrics) if judged else None, "anchors": metrics.ANCHORS}
    write_json(os.path.join(out_dir, "summary.json"), summary)
    with open(os.path.join(out_dir, "summary.md"), "w", encoding="utf-8") as fh:
        fh.write(summary_markdown(summary))
    return summary
