"""One harvest run judged: its records (harvest.json, report.json, sim.yaml) -> every open boll's outcome, the
figures, the field plot.

The farm is the run's (sim.yaml), the route's lanes and headings come from :mod:`.route`; which bolls
the arm can reach from them is cottonsim_experiments.harvest.reachability's verdict, the figures are
cottonsim_experiments.harvest.metrics' and the plot cottonsim_experiments.harvest.field_plot's (all
imported when needed: without them :class:`HarvestEvaluationError` says what is missing, and no figure
is made up). The bolls counted are those open at the start on the plants of the rows beside the
route's lanes (both faces of each plant).
"""
from __future__ import annotations

import json
import os
from typing import Dict, Optional, Sequence

from cottonsim_common.config.yaml_files import load_yaml_file

from .outcomes import DEFAULT_MATCH_RADIUS_M, boll_outcomes, run_totals
from .route import lane_headings, rows_beside, serpentine_route

HARVEST_FILE = "harvest.json"
OUTCOMES_FILE = "harvest_outcomes.json"
FIGURES_FILE = "harvest_figures.json"
PLOT_FILE = "harvest_field.png"


class HarvestEvaluationError(ValueError):
    """A run cannot be judged: a record or a module of the evaluation is missing (the message says which)."""


def harvest_module(name: str):
    """cottonsim_experiments.harvest.<name> (reachability, metrics, field_plot), or a clear error."""
    import importlib

    try:
        return importlib.import_module(f"cottonsim_experiments.harvest.{name}")
    except ImportError as exc:
        raise HarvestEvaluationError(
            f"the harvest evaluation needs cottonsim_experiments.harvest.{name}, which cannot be imported ({exc}); "
            "no figures are written without it") from None


def _read_json(path: str) -> Dict:
    if not os.path.isfile(path):
        raise HarvestEvaluationError(f"{path} does not exist")
    try:
        with open(path, "r", encoding="utf-8") as fh:
            return json.load(fh)
    except ValueError as exc:
        raise HarvestEvaluationError(f"{path} is not JSON: {exc}") from None


def reachable_boll_ids(farm, lanes: Sequence[int], headings: Dict[int, float], urdf_xml: str) -> set:
    """Ids of the bolls the arm can reach from some stop on ``lanes`` (harvest.reachability)."""
    reach = harvest_module("reachability")
    lane_objects = [lane for lane in farm.lanes if lane.index in set(lanes)]
    robot = reach.robot_geometry_from_urdf(urdf_xml)
    return {v.boll_id for v in reach.farm_reachability(farm, lane_objects, robot, reach.ReachabilityConfig(),
                                                       headings) if v.reachable}


def evaluate_run(run_dir: str, lanes: Sequence[int], urdf_xml: str,
                 match_radius_m: float = DEFAULT_MATCH_RADIUS_M, plot: bool = True) -> Dict:
    """Judge the run in ``run_dir`` (module docstring); writes harvest_outcomes.json, harvest_figures.json and
    the field plot there and returns the figures."""
    from cottonsim_world.farm.config import FarmConfig
    from cottonsim_world.farm.generator import generate_farm

    harvest = _read_json(os.path.join(run_dir, HARVEST_FILE))
    report = _read_json(os.path.join(run_dir, "report.json"))
    sim_yaml = os.path.join(run_dir, "sim.yaml")
    if not os.path.isfile(sim_yaml):
        raise HarvestEvaluationError(f"{sim_yaml} does not exist")
    metrics = harvest_module("metrics")
    farm_config = FarmConfig.from_dict(load_yaml_file(sim_yaml, default={}).get("farm") or {})
    farm = generate_farm(farm_config)
    route = serpentine_route(farm_config, lanes)
    rows = set(rows_beside(farm_config, lanes))
    plant_ids = {p.plant_id for p in farm.plants if p.row in rows}
    reachable = reachable_boll_ids(farm, lanes, lane_headings(route), urdf_xml)
    outcomes = boll_outcomes(harvest, reachable, plant_ids, match_radius_m)
    totals = run_totals(report)
    figures = metrics.harvest_figures(outcomes, totals)
    with open(os.path.join(run_dir, OUTCOMES_FILE), "w", encoding="utf-8") as fh:
        json.dump({"lanes": list(lanes), "rows": sorted(rows), "totals": totals, "outcomes": outcomes}, fh, indent=1)
    with open(os.path.join(run_dir, FIGURES_FILE), "w", encoding="utf-8") as fh:
        json.dump(figures, fh, indent=1)
    if plot:
        field_plot = harvest_module("field_plot")
        records = [metrics.BollOutcome(**dict(o, position_m=tuple(o["position_m"]))) for o in outcomes]
        plants = [(p.x_m, p.y_m) for p in farm.plants if p.row in rows]
        # every row whose bolls count, beside the lanes (the rows beyond a lane count their lane-facing halves)
        xs = [farm_config.lane_x_m(k) for k in lanes] + [x for x, _ in plants]
        region = (min(xs) - 0.6, max(xs) + 0.6, farm_config.first_plant_y_m - 1.0, farm_config.last_plant_y_m + 1.0)
        field_plot.plot_harvest_field(os.path.join(run_dir, PLOT_FILE), records, plants,
                                      lanes=[lane for lane in farm.lanes if lane.index in set(lanes)],
                                      title=f"harvest of lanes {', '.join(str(k) for k in lanes)}", region=region)
    return figures


def pooled_figures(runs: Sequence[Dict], metrics=None) -> Optional[Dict]:
    """The figures over several runs' outcomes and totals together (boll ids made unique per run; times
    and contacts summed, route_time_s the mean per run, the real-time factor the field-time-weighted mean); None when no run has outcomes."""
    metrics = metrics or harvest_module("metrics")
    outcomes, totals = [], []
    for k, run in enumerate(runs):
        outcomes += [dict(o, boll_id=k * 10_000_000 + int(o["boll_id"])) for o in run["outcomes"]]
        totals.append(run["totals"])
    if not totals:
        return None
    field = sum(t["field_time_s"] for t in totals)
    picking = [t["picking_time_s"] for t in totals]
    rtf = [(t["real_time_factor"], t["field_time_s"]) for t in totals if t["real_time_factor"] is not None]
    pooled = {"field_time_s": field,
              "picking_time_s": sum(picking) if all(p is not None for p in picking) else None,
              "arm_stem_contacts": sum(t["arm_stem_contacts"] for t in totals),
              "arm_leaf_contacts": sum(t["arm_leaf_contacts"] for t in totals),
              "base_plant_contacts": sum(t["base_plant_contacts"] for t in totals),
              "route_time_s": field / len(totals),
              "real_time_factor": (sum(r * w for r, w in rtf) / sum(w for _, w in rtf)
                                   if rtf and sum(w for _, w in rtf) > 0 else None)}
    return metrics.harvest_figures(outcomes, pooled)
