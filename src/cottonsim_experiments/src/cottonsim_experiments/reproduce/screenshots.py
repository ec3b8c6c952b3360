"""Headless rviz screenshots of each bringup: Xvfb + the bringup + rviz with its config + ImageMagick's import.

For every bringup in :data:`BRINGUPS`: start a private X server (Xvfb), the
bringup's launch file(s) on their own ROS master port, rviz with the
bringup's configuration, wait until the robot has something to show, grab
the screen to ``<out_dir>/<name>.png`` and stop everything. A screenshot that
came out blank (rviz never drew) is reported as a failure, not saved as if
it were fine.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from typing import Callable, Dict, List, Mapping, Sequence, Tuple

from .launcher import free_port, start_child, stop_process_group
from .packages import package_path

# name -> (launches [(package, launch file, args)], rviz config (package, path), seconds to wait [wall])
BRINGUPS: Dict[str, Tuple[Tuple[Tuple[str, str, Mapping[str, object]], ...], Tuple[str, str], float]] = {
    "sim": ((("cottonsim_world", "sim.launch", {}),), ("cottonsim_description", "rviz/cottonsim.rviz"), 25.0),
    "gps_navigation": ((("cottonsim_experiments", "gps_navigation.launch",
                         {"real_time_factor": 1.0, "results_dir": "/tmp/cottonsim_screenshot_runs",
                          "shutdown_when_done": "false"}),),
                       ("cottonsim_navigation", "rviz/navigation.rviz"), 75.0),
    "map_navigation": ((("cottonsim_experiments", "map_navigation.launch",
                         {"real_time_factor": 1.0, "results_dir": "/tmp/cottonsim_screenshot_runs"}),),
                       ("cottonsim_navigation", "rviz/navigation.rviz"), 75.0),
    "mapping": ((("cottonsim_experiments", "mapping.launch",
                  {"real_time_factor": 1.0, "map_file": "/tmp/cottonsim_screenshot_runs/farm_slam"}),),
                ("cottonsim_navigation", "rviz/mapping.rviz"), 120.0),
    "perception": ((("cottonsim_perception", "perception_demo.launch",
                     {"results_dir": "/tmp/cottonsim_screenshot_runs", "drive": "false",
                      "config": "$(find cottonsim_world)/config/sim_in_lane.yaml"}),),
                   ("cottonsim_perception", "rviz/perception.rviz"), 60.0),
}


@dataclass(frozen=True)
class ScreenshotResult:
    name: str
    path: str
    ok: bool
    detail: str = ""


def resolve_find(value: object, find: Callable[[str], str] = package_path) -> str:
    """A launch argument with every ``$(find pkg)`` replaced by ``find(pkg)``, the package's folder
    (arguments go to roslaunch as a list, no shell expands them)."""
    return re.sub(r"\$\(find ([A-Za-z0-9_]+)\)", lambda m: find(m.group(1)), str(value))


def image_is_blank(path: str, min_std: float = 4.0) -> bool:
    """True when the PNG is missing or (nearly) one flat colour."""
    import cv2
    img = cv2.imread(path)
    return img is None or float(img.std()) < min_std


def take_screenshots(names: Sequence[str], out_dir: str, size: str = "1280x800",
                     wait_scale: float = 1.0) -> List[ScreenshotResult]:
    """Screenshot each named bringup into ``out_dir``; returns one result per bringup."""
    unknown = [n for n in names if n not in BRINGUPS]
    if unknown:
        raise ValueError(f"unknown bringup(s) {unknown}; known: {sorted(BRINGUPS)}")
    for tool in ("Xvfb", "import", "roslaunch", "rviz"):
        if shutil.which(tool) is None:
            raise ValueError(f"'{tool}' is not installed (scripts/setup.sh installs xvfb, imagemagick and rviz)")
    os.makedirs(out_dir, exist_ok=True)
    display = f":{90 + os.getpid() % 100}"
    xvfb = subprocess.Popen(["Xvfb", display, "-screen", "0", f"{size}x24", "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    results = []
    try:
        time.sleep(2.0)
        for name in names:
            results.append(_one(name, out_dir, display, wait_scale))
            print(f"screenshot {name}: {'ok' if results[-1].ok else 'FAILED'} {results[-1].detail}", flush=True)
    finally:
        stop_process_group(xvfb)
    return results


def _one(name: str, out_dir: str, display: str, wait_scale: float) -> ScreenshotResult:
    launches, (rviz_pkg, rviz_rel), wait_s = BRINGUPS[name]
    port = free_port()
    env = dict(os.environ, DISPLAY=display, ROS_MASTER_URI=f"http://localhost:{port}")
    log_path = os.path.join(tempfile.gettempdir(), f"cottonsim_screenshot_{name}.log")   # not beside the PNGs in docs/
    procs = []
    png = os.path.join(out_dir, f"{name}.png")
    with open(log_path, "w", encoding="utf-8") as log:
        try:
            for k, (pkg, launch_file, args) in enumerate(launches):
                cmd = ["roslaunch", "-p", str(port)] + ([] if k == 0 else ["--wait"]) + [pkg, launch_file] + \
                      [f"{a}:={resolve_find(v)}" for a, v in args.items()]
                procs.append(start_child(cmd, env=env, stdout=log, stderr=subprocess.STDOUT))
                time.sleep(3.0)
            # rviz reads /use_sim_time once at start: wait until the simulator's clock runs
            try:
                subprocess.run(["rostopic", "echo", "-n", "1", "/clock"], env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL, timeout=180.0, check=False)
            except subprocess.TimeoutExpired:
                log.write("[screenshots] no /clock after 180 s; starting rviz anyway\n")
            rviz_cfg = os.path.join(package_path(rviz_pkg), rviz_rel)
            procs.append(start_child(["rviz", "-d", rviz_cfg], env=env, stdout=log, stderr=subprocess.STDOUT))
            time.sleep(wait_s * wait_scale)
            grab = subprocess.run(["import", "-display", display, "-window", "root", png], env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        finally:
            for p in reversed(procs):
                stop_process_group(p)
    if grab.returncode != 0:
        return ScreenshotResult(name, png, False, f"import failed: {grab.stdout.strip()[-200:]}")
    if image_is_blank(png):
        return ScreenshotResult(name, png, False, f"the screen is blank (see {log_path})")
    return ScreenshotResult(name, png, True, png)
