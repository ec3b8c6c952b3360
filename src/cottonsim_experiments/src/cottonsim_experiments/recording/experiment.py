"""One navigation experiment's record and its report files, free of ROS.

Why: the live recorder node and the offline bag evaluator must produce the
same report from the same data, so both feed a :class:`TrajectoryLog` with
ground-truth poses and call :func:`write_experiment`.

Frames: everything here is in the simulator's *world* frame [m] (ground
truth). The planned route is brought into it from its own frame:

* GPS routes ("lat lon" files): the simulator's GPS convention
  (``cottonsim_world.geodesy.HectorGeodesy`` at the simulator's
  geodesy_reference, default 49.9 / 8.9, heading 0) maps lat/lon straight to
  world x/y, so errors can be computed in metres as well as in degrees (the
  paper's E for GPS routes), independent of the robot's own map frame.
* map routes: the map frame starts at Home (the spawn pose), so
  world = Home composed with the map x/y.

Files written into the run folder: ``report.json`` (the keys of
:func:`cottonsim_navigation.evaluation.metrics.report_dict` plus
``run_name``, ``complete``, ``incomplete_reason``, ``waypoints_file`` and
``navigator``), ``trajectory.csv`` (t_s, x_m, y_m, yaw_rad; lat/lon too for
GPS runs) and ``trajectory.png`` (planned blue vs actual red over the plants,
like the paper's Fig. 14).
"""
from __future__ import annotations

import csv
import json
import math
import os
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence

import numpy as np

from cottonsim_navigation.evaluation.metrics import report_dict
from cottonsim_navigation.waypoints.files import GpsWaypoint, MapWaypoint

MODES = ("gps", "map")
REPORT_NAME = "report.json"
TRAJECTORY_CSV = "trajectory.csv"
TRAJECTORY_PNG = "trajectory.png"


@dataclass(frozen=True)
class TrajectoryLogConfig:
    """How densely the ground-truth trajectory is kept.

    min_period_s: keep a pose only when at least this much sim time [s] has
    passed since the last kept one (0 keeps all); 0.05 s is 2.5 cm at the
    route's 0.5 m/s, well under the 0.10 m completion radius.
    """

    min_period_s: float = 0.05

    def __post_init__(self) -> None:
        if not (math.isfinite(self.min_period_s) and self.min_period_s >= 0.0):
            raise ValueError(f"min_period_s must be finite and >= 0, got {self.min_period_s!r}")


class TrajectoryLog:
    """A growing list of (t_s, x_m, y_m, yaw_rad) ground-truth samples (world frame).

    Samples with non-finite values are refused (``add`` returns False), as are
    samples that arrive sooner than ``min_period_s`` after the last kept one
    or go back in time (a restarted clock).
    """

    def __init__(self, config: TrajectoryLogConfig = TrajectoryLogConfig()):
        self.config = config
        self._rows: List[tuple] = []

    def __len__(self) -> int:
        return len(self._rows)

    def add(self, t_s: float, x_m: float, y_m: float, yaw_rad: float) -> bool:
        values = (float(t_s), float(x_m), float(y_m), float(yaw_rad))
        if not all(math.isfinite(v) for v in values):
            return False
        if self._rows:
            dt = values[0] - self._rows[-1][0]
            if dt < 0.0 or dt < self.config.min_period_s:
                return False
        self._rows.append(values)
        return True

    @property
    def array(self) -> np.ndarray:
        """(N, 4) t_s, x_m, y_m, yaw_rad."""
        return np.array(self._rows, dtype=float).reshape(-1, 4)

    @property
    def duration_s(self) -> float:
        return self._rows[-1][0] - self._rows[0][0] if len(self._rows) > 1 else 0.0


@dataclass(frozen=True)
class SimWorld:
    """What the evaluation needs to know about the simulated farm (world frame).

    home: the spawn pose (x_m, y_m, yaw_rad); plant_xy: (P, 2) stems [m];
    lanes: lane objects (x_m, y_start_m, y_end_m) for the cross-track error;
    geodesy: the simulator's world <-> lat/lon mapping (HectorGeodesy).
    """

    home: object
    plant_xy: np.ndarray
    lanes: tuple
    geodesy: object


def sim_world_from_settings(settings: Optional[dict] = None) -> SimWorld:
    """Rebuild the farm the simulator runs from its settings (the ~sim parameter / sim.yaml shape).

    The farm generator is deterministic for a given FarmConfig, so this gives
    exactly the simulator's plants, lanes and Home; bad settings raise
    ValueError naming the key.
    """
    from cottonsim_world.config_io import simulator_config_from_dict
    from cottonsim_world.farm.generator import generate_farm
    from cottonsim_world.geodesy import HectorGeodesy

    config = simulator_config_from_dict(dict(settings or {}))
    farm = generate_farm(config.farm)
    return SimWorld(home=farm.spawn, plant_xy=farm.plant_positions(), lanes=tuple(farm.lanes),
                    geodesy=HectorGeodesy(*config.geodesy_reference))


def farm_lanes_gps(world: SimWorld) -> List[tuple]:
    """The farm's lane centre lines as (GpsWaypoint start, GpsWaypoint end) pairs [deg].

    What a surveyed farm would give the robot: each lane's centre line from
    its first to its last plant (world y_start_m .. y_end_m at x_m), through
    the simulator's GPS convention. The GPS navigator's ~lanes_file reads them.
    """
    out = []
    for lane in world.lanes:
        x = np.array([lane.x_m, lane.x_m], dtype=float)
        y = np.array([lane.y_start_m, lane.y_end_m], dtype=float)
        lat, lon, _ = world.geodesy.world_to_geodetic(x, y, np.zeros(2))
        lat, lon = np.atleast_1d(lat), np.atleast_1d(lon)
        out.append((GpsWaypoint(float(lat[0]), float(lon[0]), f"lane {lane.index} start"),
                    GpsWaypoint(float(lat[1]), float(lon[1]), f"lane {lane.index} end")))
    return out


def planned_world_from_gps(waypoints: Sequence[GpsWaypoint], geodesy) -> np.ndarray:
    """GPS waypoints -> (N, 2) world x/y [m] through the simulator's geodesy (HectorGeodesy-like)."""
    if len(waypoints) == 0:
        raise ValueError("no GPS waypoints")
    lat = np.array([w.lat for w in waypoints], dtype=float)
    lon = np.array([w.lon for w in waypoints], dtype=float)
    x, y, _ = geodesy.geodetic_to_world(lat, lon, np.zeros(len(lat)))
    return np.stack([np.asarray(x, dtype=float), np.asarray(y, dtype=float)], axis=1)


def planned_world_from_map(waypoints: Sequence[MapWaypoint], home) -> np.ndarray:
    """Map-frame waypoints -> (N, 2) world x/y [m]; the map frame is Home (x_m, y_m, yaw_rad, world)."""
    if len(waypoints) == 0:
        raise ValueError("no map waypoints")
    c, s = math.cos(home.yaw_rad), math.sin(home.yaw_rad)
    return np.array([[home.x_m + c * w.x_m - s * w.y_m, home.y_m + s * w.x_m + c * w.y_m] for w in waypoints],
                    dtype=float)


def _empty_report(mode: str, n_waypoints: int, sim_duration_s: float, wall_duration_s: float,
                  plant_contacts: int) -> Dict[str, object]:
    """The report's keys when nothing was recorded (no trajectory to measure)."""
    return {"mode": mode, "waypoints": int(n_waypoints), "reached": 0, "ae_m": None, "rmse_m": None,
            "cr_percent": None, "cr_threshold": None, "cr_percent_010m": None,
            "sim_duration_s": float(sim_duration_s), "wall_duration_s": float(wall_duration_s),
            "real_time_factor": (float(sim_duration_s) / wall_duration_s) if wall_duration_s > 0 else None,
            "plant_contacts": int(plant_contacts), "cross_track_mean_m": None, "cross_track_max_m": None}


def experiment_report(mode: str, planned_world_xy, trajectory, sim_duration_s: float, wall_duration_s: float,
                      plant_contacts: int = 0, lanes=None, geodesy=None, planned_latlon=None) -> Dict[str, object]:
    """The metrics of a run (report_dict keys) from world-frame data.

    mode 'gps' needs ``geodesy`` (world -> lat/lon of the actual trajectory)
    and ``planned_latlon`` ((N, 2) lat, lon [deg] as in the waypoint file), so
    E is measured in degrees (threshold 5e-6 deg) as in the paper, and in
    metres for ae_m / rmse_m / cr_percent_010m. trajectory: (M, >=3) with
    columns t_s, x_m, y_m (as :attr:`TrajectoryLog.array`).
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    planned = np.asarray(planned_world_xy, dtype=float).reshape(-1, 2)
    traj = np.asarray(trajectory, dtype=float)
    if traj.size == 0:
        return _empty_report(mode, len(planned), sim_duration_s, wall_duration_s, plant_contacts)
    if traj.ndim != 2 or traj.shape[1] < 3:
        raise ValueError(f"trajectory must be (M, >=3) t_s, x_m, y_m, got shape {traj.shape}")
    actual_xy = traj[:, 1:3]
    if mode == "map":
        return report_dict("map", planned, actual_xy, sim_duration_s, wall_duration_s, plant_contacts,
                           lanes=lanes)
    if geodesy is None or planned_latlon is None:
        raise ValueError("a GPS report needs geodesy and planned_latlon")
    lat, lon, _ = geodesy.world_to_geodetic(actual_xy[:, 0], actual_xy[:, 1], np.zeros(len(actual_xy)))
    actual_latlon = np.stack([np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)], axis=1)
    return report_dict("gps", np.asarray(planned_latlon, dtype=float).reshape(-1, 2), actual_latlon,
                       sim_duration_s, wall_duration_s, plant_contacts, lanes=lanes,
                       planned_xy_m=planned, actual_xy_m=actual_xy)


def write_experiment(out_dir: str, mode: str, planned_world_xy, trajectory, sim_duration_s: float,
                     wall_duration_s: float, plant_contacts: int = 0, lanes=None, plant_xy=None,
                     geodesy=None, planned_latlon=None, complete: bool = True, incomplete_reason: str = "",
                     run_name: str = "", waypoints_file: str = "", navigator: Optional[dict] = None,
                     plot: bool = True, extra: Optional[dict] = None) -> Dict[str, object]:
    """Write trajectory.csv, (plot=True) trajectory.png and then report.json into ``out_dir``; return the report.

    An incomplete run (``complete=False``: shut down early, navigator never
    finished) still gets every file, with ``complete: false`` and the reason.
    ``extra``: more report keys (e.g. the localisation error of a map run).
    """
    report = experiment_report(mode, planned_world_xy, trajectory, sim_duration_s, wall_duration_s,
                               plant_contacts, lanes, geodesy, planned_latlon)
    report.update({"run_name": run_name, "complete": bool(complete),
                   "incomplete_reason": "" if complete else (incomplete_reason or "run did not finish"),
                   "waypoints_file": waypoints_file, "navigator": navigator or {}})
    report.update(extra or {})
    os.makedirs(out_dir, exist_ok=True)
    traj = np.asarray(trajectory, dtype=float).reshape(-1, 4) if np.size(trajectory) else np.zeros((0, 4))
    with open(os.path.join(out_dir, TRAJECTORY_CSV), "w", newline="") as fh:
        w = csv.writer(fh)
        gps = mode == "gps" and geodesy is not None
        w.writerow(["t_s", "x_m", "y_m", "yaw_rad"] + (["lat_deg", "lon_deg"] if gps else []))
        if gps and len(traj):
            lat, lon, _ = geodesy.world_to_geodetic(traj[:, 1], traj[:, 2], np.zeros(len(traj)))
            lat, lon = np.atleast_1d(lat), np.atleast_1d(lon)
        for k, (t, x, y, a) in enumerate(traj):
            row = [f"{t:.3f}", f"{x:.4f}", f"{y:.4f}", f"{a:.5f}"]
            if gps:
                row += [f"{lat[k]:.10f}", f"{lon[k]:.10f}"]
            w.writerow(row)
    if plot:
        from cottonsim_navigation.evaluation.plots import plot_trajectory
        title = f"{run_name or 'run'} ({mode}): CR {_fmt(report['cr_percent'])} %, contacts {report['plant_contacts']}"
        if not complete:
            title += " [incomplete]"
        plot_trajectory(os.path.join(out_dir, TRAJECTORY_PNG), planned_world_xy, traj[:, 1:3], plant_xy,
                        title=title)
    # the report comes last and appears at once (rename), so a reader that sees it sees every file
    tmp = os.path.join(out_dir, REPORT_NAME + ".tmp")
    with open(tmp, "w") as fh:
        json.dump(report, fh, indent=1)
    os.replace(tmp, os.path.join(out_dir, REPORT_NAME))
    return report


def _fmt(v) -> str:
    return "-" if v is None else f"{v:.1f}"


def summary_line(report: Dict[str, object]) -> str:
    """One human-readable line with the headline numbers of a report."""
    def f(key, scale=1.0, digits=3):
        v = report.get(key)
        return "-" if v is None else f"{v * scale:.{digits}f}"
    return (f"{report.get('mode')} route: CR {f('cr_percent', digits=1)} % "
            f"({report.get('reached')}/{report.get('waypoints')}, r={report.get('cr_threshold')}), "
            f"CR@0.10m {f('cr_percent_010m', digits=1)} %, AE {f('ae_m')} m, RMSE {f('rmse_m')} m, "
            f"cross-track mean {f('cross_track_mean_m', 100, 1)} cm max {f('cross_track_max_m', 100, 1)} cm, "
            f"contacts {report.get('plant_contacts')}, sim {f('sim_duration_s', digits=1)} s, "
            f"wall {f('wall_duration_s', digits=1)} s, RTF {f('real_time_factor', digits=2)}"
            + ("" if report.get("complete", True) else " [INCOMPLETE]"))
