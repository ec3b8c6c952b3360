"""What the paper's experiments share: the workspace, the routes, their sim settings, reports; the perception tables.

Every experiment writes into its own folder under the results root; the route experiments and the
row-spacing study run as sweeps (:mod:`.route_experiments`), the perception tables here:

  perception/  <table>.json from the evaluate command, summary.json

Nothing here imports ROS: bringups run as child processes (see :mod:`.launcher`), the perception
tables through the evaluate command.
"""
from __future__ import annotations

import copy
import json
import os
import subprocess
import time
from dataclasses import dataclass
from typing import Dict, Mapping, Optional

import yaml

from cottonsim_common.config.yaml_files import load_yaml_file

from ..sweep.records import read_json_mapping
from .packages import package_path, rosrun_command


@dataclass(frozen=True)
class Workspace:
    """Where things are: the results root and the folders of the packages the runs read [paths].

    A package folder left empty is looked up with rospkg (its source folder in a devel space, its
    share/ folder in an install space); tests give folders of their own.
    """

    results: str
    navigation: str = ""
    perception: str = ""
    experiments: str = ""

    def __post_init__(self) -> None:
        if not self.results:
            raise ValueError("results must name the results folder")
        object.__setattr__(self, "results", os.path.abspath(self.results))
        for name in ("navigation", "perception", "experiments"):
            if not getattr(self, name):
                object.__setattr__(self, name, package_path(f"cottonsim_{name}"))


# The two waypoint routes of the paper: launch file, route file, sim settings, mode, and whether the
# farm is re-drawn per seed. The GPS route drives a new farm per seed (plant jitter, yaw, shapes);
# the map route keeps the farm of its sim settings (farm seed 0), because the shipped SLAM map
# (config/maps/farm_slam) is a map of that farm: another farm would not be the mapped one.
ROUTES = {
    "gps_route": {"launch": "gps_navigation.launch", "mode": "gps", "seed_farm": True,
                  "waypoints": "config/waypoints/route_gps.txt", "sim_config": "config/sim_navigation.yaml"},
    "map_route": {"launch": "map_navigation.launch", "mode": "map", "seed_farm": False,
                  "waypoints": "config/waypoints/route_map.csv", "sim_config": "config/sim_navigation.yaml"},
}


def seed_overrides(experiment: str, seed: int) -> Dict:
    """The sim-settings overrides of one run of ``experiment`` with ``seed``.

    Always the simulator's seed (sensor noise, solver order); the farm's seed too only where the
    experiment re-draws the farm per seed (the GPS route). The map route keeps the mapped farm.
    """
    if experiment not in ROUTES:
        raise ValueError(f"experiment must be one of {sorted(ROUTES)}, got {experiment!r}")
    overrides: Dict = {"seed": int(seed)}
    if ROUTES[experiment]["seed_farm"]:
        overrides["farm"] = {"seed": int(seed)}
    return overrides


def deep_merge(base: Mapping, override: Mapping) -> Dict:
    """``base`` with ``override`` merged in, nested dicts key by key (inputs are not changed)."""
    out = copy.deepcopy(dict(base))
    for key, value in override.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def write_sim_config(base_path: str, overrides: Mapping, out_path: str) -> str:
    """Write base sim settings (YAML) with ``overrides`` merged in; returns ``out_path``.

    The merged settings are checked with the simulator's own parser first, so a misspelt or invalid
    override fails here with the simulator's message (ValueError) instead of in a launched bridge."""
    from cottonsim_world.config_io import simulator_config_from_dict

    base = load_yaml_file(base_path, default={})
    if not isinstance(base, Mapping):
        raise ValueError(f"{base_path}: simulator settings must be a YAML mapping")
    merged = deep_merge(base, overrides)
    try:
        simulator_config_from_dict(dict(merged))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"simulator settings {base_path} + overrides {dict(overrides)}: {exc}") from exc
    os.makedirs(os.path.dirname(os.path.abspath(out_path)), exist_ok=True)
    with open(out_path, "w", encoding="utf-8") as fh:
        fh.write(f"# {os.path.basename(base_path)} with the experiment's overrides {dict(overrides)}\n")
        yaml.safe_dump(merged, fh, sort_keys=False)
    return out_path


def widest_collision_radius_m(farm_config) -> Optional[float]:
    """The largest horizontal collision radius among the farm's plants [m] (None without a farm)."""
    if farm_config is None:
        return None
    from cottonsim_world.farm.generator import generate_farm

    radii = [pr.size[0] for plant in generate_farm(farm_config).plants for pr in plant.model.collision
             if pr.shape == "cylinder"]
    return max(radii) if radii else None


def read_trajectory_y(path: str) -> Optional[list]:
    """The world y column [m] of a recorder's trajectory.csv, or None when it is missing or unreadable."""
    try:
        with open(path, "r", encoding="utf-8") as fh:
            header = fh.readline().strip().split(",")
            col = header.index("y_m")
            return [float(line.split(",")[col]) for line in fh if line.strip()]
    except (OSError, ValueError, IndexError):
        return None


def machine_description() -> str:
    """The machine a run used: architecture, cores, Python, load average when asked (for the results page)."""
    import platform

    return (f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"load average {os.getloadavg()[0]:.1f} at the start")


def write_json(path: str, data) -> None:
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(data, fh, indent=1, allow_nan=True)
        fh.write("\n")


# Figures compared between the online report and the one recomputed from the bag [same units].
OFFLINE_TOLERANCES = {"cr_percent": 1e-6, "cr_percent_010m": 1e-6, "reached": 0, "plant_contacts": 0,
                      "ae_m": 0.005, "rmse_m": 0.005, "cross_track_mean_m": 0.005, "sim_duration_s": 1.0}


def compare_reports(online: Mapping, offline: Mapping, tolerances: Mapping[str, float] = OFFLINE_TOLERANCES
                    ) -> Dict[str, object]:
    """Which headline figures of two reports differ by more than their tolerance."""
    differences = {}
    for key, tol in tolerances.items():
        a, b = online.get(key), offline.get(key)
        if a is None and b is None:
            continue
        if a is None or b is None or not (abs(float(a) - float(b)) <= tol):
            differences[key] = {"online": a, "offline": b, "tolerance": tol}
    return {"matches": not differences, "differences": differences}


def offline_report_check(mode: str, run_dir: str, waypoints: str, sim_yaml: str, report: Mapping) -> Dict:
    """The report recomputed from <run_dir>/run.bag alone (``evaluate_bag``, into <run_dir>/offline/) compared
    with the online ``report``: {"matches": bool, "differences": ...} or {"matches": False, "error": ...}."""
    out = os.path.join(run_dir, "offline")
    cmd = rosrun_command("cottonsim_experiments", "evaluate_bag",
                         [os.path.join(run_dir, "run.bag"), "--waypoints", waypoints, "--mode", mode,
                          "--sim-config", sim_yaml, "--out", out])
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    offline = read_json_mapping(os.path.join(out, "report.json"))
    if proc.returncode != 0 or offline is None:
        return {"matches": False, "error": proc.stdout.strip()[-500:]}
    return compare_reports(report, offline)


# The perception tables: (name, task, dataset folder relative to the original data root or absolute, splits).
PERCEPTION_TABLES = (
    ("seg_original", "seg", "Segmentation", "valid,test"),
    ("det_original", "det", "Detection", "valid,test"),
    ("det_original_sim_weights", "det", "Detection", "valid,test"),
    ("seg_original_fine_weights", "seg", "Segmentation", "valid,test"),
)
# Weights of each table (relative to cottonsim_perception): two scene segmenters, the default
# one and a finer-masked, slower one (scene_segmenter_fine.pt); two boll detectors, one trained
# for the paper's images and one for the simulator's (weights/README.md).
DEFAULT_WEIGHTS = {"seg": "weights/scene_segmenter.pt", "det": "weights/boll_detector.pt"}
TABLE_WEIGHTS = {"det_original_sim_weights": "weights/boll_detector_sim.pt",
                 "det_synthetic": "weights/boll_detector_sim.pt",
                 "det_synthetic_no_ignore": "weights/boll_detector_sim.pt",
                 "seg_original_fine_weights": "weights/scene_segmenter_fine.pt",
                 "seg_synthetic_fine_weights": "weights/scene_segmenter_fine.pt"}


def run_perception(ws: Workspace, original_data: str, synthetic_data: Optional[str] = None,
                   synthetic_images: int = 120, synthetic_test_seeds: str = "900-904") -> Dict:
    """Tables 2 and 3: the evaluate command on the paper's images and on held-out synthetic frames.

    The synthetic frames are generated here from farm seeds ``synthetic_test_seeds``
    (never used for training: see weights/README.md) into ``synthetic_data``
    (default results/perception/synthetic) unless that folder already holds them.
    Boll detection on them is evaluated twice: predictions on ignore boxes
    (bolls beyond the labels' working range) left out (``det_synthetic``)
    and counted as false positives (``det_synthetic_no_ignore``).
    """
    out_dir = os.path.join(ws.results, "perception")
    os.makedirs(out_dir, exist_ok=True)
    tables = [(name, task, os.path.join(original_data, sub), split, ())
              for name, task, sub, split in PERCEPTION_TABLES]
    synthetic = synthetic_data or os.path.join(out_dir, "synthetic")
    if synthetic_images > 0:
        if not os.path.isdir(os.path.join(synthetic, "seg")):
            print(f"perception: generating {synthetic_images} held-out synthetic frames per task "
                  f"(farm seeds {synthetic_test_seeds})", flush=True)
            subprocess.run(rosrun_command("cottonsim_perception", "generate_dataset",
                                          ["--task", "both", "--out", synthetic, "--images", "0",
                                           "--test-images", str(synthetic_images), "--seeds", "",
                                           "--test-seeds", synthetic_test_seeds]), check=True)
        det = os.path.join(synthetic, "det")
        # bolls beyond the labels' working range are ignore boxes; the strict row counts
        # predictions on them as false positives (docs/perception_data.md)
        tables += [("seg_synthetic", "seg", os.path.join(synthetic, "seg"), "test", ()),
                   ("seg_synthetic_fine_weights", "seg", os.path.join(synthetic, "seg"), "test", ()),
                   ("det_synthetic", "det", det, "test", ()),
                   ("det_synthetic_no_ignore", "det", det, "test", ("--no-ignore",))]
    summary = {"experiment": "perception", "tables": {}}
    for name, task, data, split, extra_args in tables:
        out_json = os.path.join(out_dir, f"{name}.json")
        weights = os.path.join(ws.perception, TABLE_WEIGHTS.get(name, DEFAULT_WEIGHTS[task]))
        print(f"perception: {name} ({task}, {data}, split {split})", flush=True)
        t0 = time.monotonic()
        proc = subprocess.run(rosrun_command("cottonsim_perception", "evaluate",
                                             ["--task", task, "--data", data, "--weights", weights, "--split", split,
                                              "--json", out_json, *extra_args]),
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        summary["tables"][name] = {"task": task, "data": data, "split": split, "weights": weights,
                                   "json": out_json, "ok": proc.returncode == 0,
                                   "wall_s": time.monotonic() - t0,
                                   "error": "" if proc.returncode == 0 else proc.stdout.strip()[-500:]}
    write_json(os.path.join(out_dir, "summary.json"), summary)
    return summary

