"""The vision ablation: the same route with Cotton-Eye in the loop and without, side by side (free of ROS).

Input: the run reports (report.json, as the experiment recorder writes them)
of the two modes for one seed; output: a markdown table, one row per figure,
and the figures as a dict for summary files. A figure a report lacks shows
as "-" (e.g. the vision_* keys of a run without vision). :func:`ablation_section`
builds the results page's subsection from the two route folders.
"""
from __future__ import annotations

import json
import math
import os
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

# (report key, label, scale, digits)
ABLATION_ROWS: Sequence[Tuple[str, str, float, int]] = (
    ("cr_percent", "CR [%] (paper's threshold)", 1.0, 1),
    ("cr_percent_010m", "CR at 0.10 m [%]", 1.0, 1),
    ("ae_m", "AE [m]", 1.0, 3),
    ("rmse_m", "RMSE [m]", 1.0, 3),
    ("cross_track_mean_m", "in-row cross-track, mean [cm]", 100.0, 2),
    ("cross_track_max_m", "in-row cross-track, max [cm]", 100.0, 2),
    ("plant_contacts", "plant contacts", 1.0, 0),
    ("halts", "halts at bolls", 1.0, 0),
    ("halt_time_s", "time halted [s]", 1.0, 1),
    ("sim_duration_s", "route time (sim) [s]", 1.0, 1),
    ("real_time_factor", "real-time factor", 1.0, 2),
    ("vision_row_centring_per_sim_s", "segmented frames per sim second", 1.0, 1),
    ("vision_no_estimate_fraction", "frames with no estimate [%]", 100.0, 1),
    ("vision_coords_per_sim_s", "row-centring commands per sim second", 1.0, 1),
    ("vision_corrections_per_sim_s", "move_base corrections per sim second", 1.0, 1),
    ("vision_boll_verdicts_per_sim_s", "boll verdicts per sim second (both cameras)", 1.0, 1),
    ("vision_in_reach_fraction", "verdicts with a boll in reach [%]", 100.0, 1),
)


def _value(report: Optional[Mapping], key: str) -> Optional[float]:
    if not report:
        return None
    v = report.get(key)
    if v is None and key in ("halts", "halt_time_s"):
        v = (report.get("navigator") or {}).get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return None
    return float(v)


def _fmt(v: Optional[float], scale: float, digits: int) -> str:
    return "-" if v is None else f"{v * scale:.{digits}f}"


def ablation_figures(with_vision: Optional[Mapping], without_vision: Optional[Mapping]) -> Dict[str, Dict]:
    """{key: {"vision": value or None, "no_vision": value or None}} for every row of the table."""
    return {key: {"vision": _value(with_vision, key), "no_vision": _value(without_vision, key)}
            for key, _, _, _ in ABLATION_ROWS}


def ablation_table(with_vision: Optional[Mapping], without_vision: Optional[Mapping]) -> List[str]:
    """Markdown lines: | figure | with vision | without vision |."""
    lines = ["| figure | with vision (Cotton-Eye in the loop) | without vision (LiDAR + GPS) |", "|---|---|---|"]
    for key, label, scale, digits in ABLATION_ROWS:
        lines.append(f"| {label} | {_fmt(_value(with_vision, key), scale, digits)} | "
                     f"{_fmt(_value(without_vision, key), scale, digits)} |")
    return lines


def _reports_by_seed(summary: Optional[Mapping]) -> Dict[int, Mapping]:
    out = {}
    for run in (summary or {}).get("runs", []):
        if run.get("report") is not None:
            out[int(run["seed"])] = run["report"]
    return out


def ablation_markdown(summary_vision: Optional[Mapping], summary_no_vision: Optional[Mapping]) -> List[str]:
    """Markdown lines, one table per seed both modes ran, from two route summaries (summary.json).

    Empty when no seed has a report in both.
    """
    on, off = _reports_by_seed(summary_vision), _reports_by_seed(summary_no_vision)
    lines: List[str] = []
    for seed in sorted(set(on) & set(off)):
        lines += [f"Seed {seed}:", ""] + ablation_table(on[seed], off[seed]) + [""]
    return lines


def _read_summary(path: str) -> Optional[Mapping]:
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except (OSError, ValueError):
        return None


def ablation_section(results_root: str, experiment: str) -> List[str]:
    """The results page's ablation subsection of one route (results/<experiment>/ beside
    results/<experiment>_no_vision/); empty when they share no seed."""
    on = _read_summary(os.path.join(results_root, experiment, "summary.json"))
    off = _read_summary(os.path.join(results_root, f"{experiment}_no_vision", "summary.json"))
    if not (on or {}).get("vision") or off is None:
        return []
    table = ablation_markdown(on, off)
    if not table:
        return []
    cmd = f"rosrun cottonsim_navigation reproduce {experiment.replace('_', '-')} --vision both"
    return [f"### Vision ablation: {experiment}", "",
            f"Command: `{cmd}` (writes `results/{experiment}/` and `results/{experiment}_no_vision/`). "
            f"Machine: {on.get('machine', 'not recorded')}.", ""] + table
