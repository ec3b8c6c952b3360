"""docs/results.md, generated from the results folders of the experiments (never typed by hand).

``render_results(results_root, doc_path)`` reads what ``reproduce`` wrote
(see :mod:`.runs`), copies the plots next to the document (docs/results/),
and writes one section per experiment with our figures beside the paper's
and the command that produced them. An experiment without results gets a
line saying so and the command that would produce them.
"""
from __future__ import annotations

import datetime
import os
import shutil
from typing import List, Optional, Sequence

from .harvest import anchors_lines, figures_table
from .row_spacing import seeds_markdown, summary_markdown
from ..sweep.records import read_json_mapping
from cottonsim_navigation.evaluation.vision_ablation import ablation_section
from cottonsim_perception.evaluation.paper import PAPER_TABLES
from .seeds import format_spread

# The paper's published figures (its section 3, Tables 2 and 3, Fig. 3a).
PAPER_ROUTES = {
    "gps_route": {"cr_percent": "100 (at 5e-6 deg)", "ae_m": "0 (in degrees)", "rmse_m": "0 (in degrees)",
                  "sim_duration_s": "20 min 42 s", "cr_percent_010m": "-", "plant_contacts": "-",
                  "cross_track_mean_m": "-", "real_time_factor": "-"},
    "map_route": {"cr_percent": "96.7 (at 0.25 m)", "ae_m": "0.137", "rmse_m": "0.156",
                  "sim_duration_s": "31 min 7 s", "cr_percent_010m": "-", "plant_contacts": "-",
                  "cross_track_mean_m": "-", "real_time_factor": "-"},
}
TARGETS = {
    "gps_route": {"cr_percent": "100", "cr_percent_010m": "100", "plant_contacts": "0",
                  "cross_track_mean_m": "<= 3 cm", "sim_duration_s": "<= 10 min", "real_time_factor": "> 1"},
    "map_route": {"cr_percent": "100", "ae_m": "<= 0.05", "rmse_m": "<= 0.06", "plant_contacts": "0",
                  "sim_duration_s": "<= 10 min", "localization_error_mean_m": "<= 0.05",
                  "localization_error_max_m": "<= 0.15"},
}
# (report key, label, scale, digits)
ROUTE_ROWS = (("cr_percent", "CR [%] (paper's threshold)", 1.0, 1),
              ("cr_percent_010m", "CR at 0.10 m [%]", 1.0, 1),
              ("ae_m", "AE [m]", 1.0, 3),
              ("rmse_m", "RMSE [m]", 1.0, 3),
              ("plant_contacts", "plant contacts", 1.0, 1),
              ("cross_track_mean_m", "in-row cross-track, mean [cm]", 100.0, 1),
              ("cross_track_max_m", "in-row cross-track, max [cm]", 100.0, 1),
              ("localization_error_mean_m", "localisation error vs truth, mean [m]", 1.0, 3),
              ("localization_error_max_m", "localisation error vs truth, max [m]", 1.0, 3),
              ("sim_duration_s", "route time (sim) [min]", 1.0 / 60.0, 2),
              ("real_time_factor", "real-time factor", 1.0, 2))
# The paper's Tables 2 (its validation split, during training) and 3 (its test split) come from
# cottonsim_perception.evaluation.paper: split -> table.
PAPER_TABLE_OF_SPLIT = {"valid": "table2", "test": "table3"}
COMMANDS = {
    "gps_route": "rosrun cottonsim_experiments reproduce gps-route --seeds 0 1 2",
    "map_route": "rosrun cottonsim_experiments reproduce map-route --seeds 0 1 2",
    "row_spacing": "rosrun cottonsim_experiments reproduce row-spacing",
    "perception": "rosrun cottonsim_experiments reproduce perception",
    "harvest": "rosrun cottonsim_experiments reproduce harvest --seeds 0 1 2",
}




def _route_section(name: str, title: str, results_root: str, doc_dir: str) -> List[str]:
    out = [f"## {title}", "", f"Command: `{COMMANDS[name]}` (writes `results/{name}/`).", ""]
    summary = read_json_mapping(os.path.join(results_root, name, "summary.json"))
    if summary is None:
        return out + ["No results yet: run the command above.", ""]
    spread = summary.get("spread", {})
    n_runs = summary.get("runs_with_report", 0)
    out += [f"Seeds {summary.get('seeds')} ({n_runs} runs with a report); mean ± sample standard deviation "
            f"(min..max) over the seeds. Machine: {summary.get('machine', 'not recorded')}. "
            f"Cotton-Eye in the loop: {'yes' if summary.get('vision') else 'no (LiDAR + GPS)'}.", "",
            "| figure | ours | paper | target |", "|---|---|---|---|"]
    for key, label, scale, digits in ROUTE_ROWS:
        if key not in spread:
            continue
        out.append(f"| {label} | {format_spread(spread[key], scale, digits)} | "
                   f"{PAPER_ROUTES[name].get(key, '-')} | {TARGETS[name].get(key, '-')} |")
    out += ["", "| seed | complete | CR [%] | AE [m] | RMSE [m] | contacts | sim [min] | offline from bag |",
            "|---|---|---|---|---|---|---|---|"]
    for run in summary.get("runs", []):
        r = run.get("report") or {}
        off = run.get("offline")
        off_txt = "-" if off is None else ("reproduces the report" if off.get("matches") else
                                            f"differs: {sorted((off.get('differences') or {}).keys()) or off.get('error', '')}")
        def g(key, scale=1.0, d=3):
            v = r.get(key)
            return "-" if v is None else f"{v * scale:.{d}f}"
        out.append(f"| {run.get('seed')} | {r.get('complete', False)} | {g('cr_percent', d=1)} | {g('ae_m')} | "
                   f"{g('rmse_m')} | {r.get('plant_contacts', '-')} | {g('sim_duration_s', 1 / 60, 2)} | {off_txt} |")
    first = next((run for run in summary.get("runs", []) if run.get("report")), None)
    if first is not None:
        plot = os.path.join(first["run_dir"], "trajectory.png")
        if os.path.isfile(plot):
            rel = os.path.join("results", f"{name}_seed_{first['seed']}.png")
            os.makedirs(os.path.join(doc_dir, "results"), exist_ok=True)
            shutil.copyfile(plot, os.path.join(doc_dir, rel))
            out += ["", f"Planned vs actual trajectory, seed {first['seed']} (the paper's Fig. 14 style):", "",
                    f"![{name} trajectory]({rel})"]
    return out + [""]


def _row_spacing_section(results_root: str) -> List[str]:
    out = ["## Row-spacing study (the paper's Fig. 3a)", "",
           f"Command: `{COMMANDS['row_spacing']}` (writes `results/row_spacing/`). Each spacing is one full "
           "GPS-navigation bringup on a two-row farm: the robot drives from Home into the lane between the rows "
           "(entry, middle and exit waypoints on the centre line); it traverses when it reaches all three without "
           "touching a plant.", ""]
    summary = read_json_mapping(os.path.join(results_root, "row_spacing", "summary.json"))
    if summary is None or "per_seed" not in summary:
        return out + ["No results yet: run the command above.", ""]
    out += [seeds_markdown(summary), ""]
    first = summary["per_seed"][0]
    radius, limit = first.get("plant_collision_radius_m"), first.get("contact_free_spacing_m")
    if radius is not None and limit is not None:
        out += [f"Why: our plants collide through a stem and three canopy cylinders whose widest radius is "
                f"{radius:.2f} m (the 0.70 m canopy's outer leaves are visual only), so a "
                f"{first['robot_width_m']:.2f} m wide robot centred in the lane clears them from "
                f"{limit:.2f} m spacing on; below that it pushes into the first plants of the row and is pinned "
                "there (the contacts and the 'stopped 0.0 m into the row' above). The paper's Gazebo plants used "
                "their leaves as collision elements and its costmap stopped the robot when the LiDAR saw the "
                "canopies inside its footprint margin, hence its 1.80 m. Our move_base did not stop the robot in front "
                "of the rows even at 1.00 m: it drove on into the first plants, so the crop damage (contacts) is what "
                "fails the narrow spacings here.", ""]
    out += [f"Seed {first['seed']} in detail:", "", summary_markdown(first), ""]
    return out


def _perception_section(results_root: str) -> List[str]:
    out = ["## Perception (the paper's Tables 2 and 3)", "",
           f"Command: `{COMMANDS['perception']}` (writes `results/perception/`): the evaluate command "
           "(`rosrun cottonsim_perception evaluate`) with the shipped weights on the original's images "
           "(valid split beside the paper's Table 2, test split beside Table 3) and on held-out synthetic frames "
           "from farm seeds never used in training. Masks for segmentation, boxes for detection; P / R / mAP50 in %. "
           "Synthetic boll labels cover the bolls within 1.5 m of the camera (the row it faces); visible bolls "
           "farther away are ignore boxes: `det_synthetic` leaves predictions on them out, "
           "`det_synthetic_no_ignore` counts them as false positives (docs/perception_data.md).",
           ""]
    summary = read_json_mapping(os.path.join(results_root, "perception", "summary.json"))
    if summary is None:
        return out + ["No results yet: run the command above.", ""]
    out += ["| data | task | split | class | ours P / R / mAP50 / mAP50-95 | paper P / R / mAP50 |",
            "|---|---|---|---|---|---|"]
    for name, table in summary.get("tables", {}).items():
        evaluation = read_json_mapping(table.get("json", ""))
        if evaluation is None:
            out.append(f"| {name} | {table.get('task')} | - | - | failed: {table.get('error', '')[:80]} | - |")
            continue
        task = table.get("task")
        for split, per_split in (evaluation.get("splits") or {}).items():
            block = per_split.get("mask") if task == "seg" else per_split.get("box")
            for row in (block or {}).get("rows", []):
                cls = row.get("class")
                paper = None
                if name.endswith("_original") and split in PAPER_TABLE_OF_SPLIT:
                    paper = PAPER_TABLES[PAPER_TABLE_OF_SPLIT[split]].get(task, {}).get(cls)
                paper_txt = "-" if paper is None else f"{paper[0]:.1f} / {paper[1]:.1f} / {paper[2]:.1f}"
                out.append(f"| {name} | {task} | {split} | {cls} | {100 * row['p']:.1f} / {100 * row['r']:.1f} / "
                           f"{100 * row['map50']:.1f} / {100 * row['map50_95']:.1f} | {paper_txt} |")
    return out + [""]


def _harvest_section(results_root: str, doc_dir: str) -> List[str]:
    out = ["## Harvest (issue: the robot picks the cotton)", "",
           f"Command: `{COMMANDS['harvest']}` (writes `results/harvest/`; `--targets ground_truth` writes "
           "`results/harvest_ground_truth/`): the GPS route with the harvest node on, row 1 harvested from both "
           "its lanes, one run per seed on the seed's farm; every open boll of the rows beside the route judged "
           "against the simulator's truth (docs/harvest.md, 'The harvest experiment'). The simulation captures a "
           "boll with the vacuum nozzle within 2 cm; it has no fibre pull-off force.", ""]
    found = False
    modes = (("harvest", "the networks' detections"), ("harvest_ground_truth", "ground truth (a study option)"))
    summaries = {name: read_json_mapping(os.path.join(results_root, name, "summary.json")) for name, _ in modes}
    for name, what in modes:
        summary = summaries[name]
        if summary is None:
            if any(v is not None for v in summaries.values()):
                out += [f"### Targets from {what}", "", f"No runs in this results folder (`results/{name}/`).", ""]
            continue
        found = True
        columns = {f"seed {r['seed']}": r.get("figures") for r in summary.get("runs", [])}
        columns["pooled"] = summary.get("pooled")
        out += [f"### Targets from {what} ({summary.get('lanes', '')})", ""] + figures_table(columns) + [""]
        for run in summary.get("runs", []):
            plot = os.path.join(run.get("run_dir", ""), "harvest_field.png")
            if os.path.isfile(plot):
                target = os.path.join(doc_dir, "results", f"{name}_seed_{run['seed']}_field.png")
                os.makedirs(os.path.dirname(target), exist_ok=True)
                shutil.copyfile(plot, target)
                out += [f"![{name} seed {run['seed']}](results/{os.path.basename(target)})", ""]
            if run.get("error"):
                out += [f"- seed {run['seed']}: {run['error']}", ""]
        out += ["Anchors (published figures of real robots):", ""] + anchors_lines(summary.get("anchors", {})) + [""]
    if not found:
        out += ["No results yet: run the command above.", ""]
    return out


SECTIONS = ("gps-route", "map-route", "row-spacing", "perception", "harvest")


def _section_lines(name: str, results_root: str, doc_dir: str) -> List[str]:
    if name == "gps-route":
        return _route_section("gps_route", "GPS-based route (the paper's section 3.3)", results_root, doc_dir) + \
            ablation_section(results_root, "gps_route")
    if name == "map-route":
        return _route_section("map_route", "Map-based route (AMCL on our SLAM map)", results_root, doc_dir) + \
            ablation_section(results_root, "map_route")
    if name == "row-spacing":
        return _row_spacing_section(results_root)
    if name == "perception":
        return _perception_section(results_root)
    if name == "harvest":
        return _harvest_section(results_root, doc_dir)
    raise ValueError(f"unknown results section {name!r}: one of {', '.join(SECTIONS)}")


def _blocks(lines: Sequence[str]) -> List[List[str]]:
    """The lines cut before every '## ' heading (the first block: what precedes the first heading)."""
    blocks: List[List[str]] = [[]]
    for line in lines:
        if line.startswith("## "):
            blocks.append([])
        blocks[-1].append(line)
    return blocks


def render_results(results_root: str, doc_path: str, sections: Optional[Sequence[str]] = None) -> str:
    """Write the results page; returns its text. sections (names of SECTIONS): only these are rendered again, in
    the page that is there (a '## ' block with the same heading is replaced, a new one appended; the others and
    the header stay as they are), for a results folder that holds some experiments only."""
    doc_dir = os.path.dirname(os.path.abspath(doc_path))
    for name in sections or ():
        if name not in SECTIONS:
            raise ValueError(f"unknown results section {name!r}: one of {', '.join(SECTIONS)}")
    if sections and os.path.isfile(doc_path):
        with open(doc_path, encoding="utf-8") as fh:
            blocks = _blocks(fh.read().split("\n"))
        for name in sections:
            for new_block in _blocks(_section_lines(name, results_root, doc_dir))[1:]:
                same = [k for k, b in enumerate(blocks) if k and b[0] == new_block[0]]
                if same:
                    blocks[same[0]] = new_block
                else:
                    if blocks[-1] and blocks[-1][-1] != "":
                        blocks[-1].append("")
                    blocks.append(new_block)
        lines = [line for block in blocks for line in block]
    else:
        lines = ["# Results: CottonSim beside the paper", "",
                 "Generated by `rosrun cottonsim_experiments reproduce results-doc --doc docs/results.md` from the "
                 "folders under `results/` "
                 f"on {datetime.date.today().isoformat()}; do not edit by hand: re-run the experiments and this "
                 "command (`--sections harvest` renders the harvest's section again and keeps the others).",
                 ""]
        for name in SECTIONS:
            lines += _section_lines(name, results_root, doc_dir)
    text = "\n".join(lines)
    os.makedirs(doc_dir, exist_ok=True)
    with open(doc_path, "w", encoding="utf-8") as fh:
        fh.write(text)
    return text
