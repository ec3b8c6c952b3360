"""Ground-truth exports of a generated farm.

Why: navigation needs a ground-truth occupancy map (to compare SLAM maps
with, or to run AMCL without mapping first), evaluation needs plant and boll
positions, and the waypoint senders need the default route in the world
frame, in the 'Home' (spawn) frame and as GPS "lat lon" lines like the
original's waypoint file.

Files written by ``export_all(farm, out_dir)``:

* ``map_world.yaml/.pgm``  occupancy of the plants' collision primitives in
  a height band (default z 0.3-0.5 m, the LiDAR's), world frame;
* ``map_home.yaml/.pgm``   the same in the Home frame (origin = spawn pose);
* ``plants.csv``  plant_id,row,index,x_m,y_m,yaw_rad,height_m (world);
* ``bolls.csv``   boll_id,plant_id,boll,x_m,y_m,z_m,radius_m,diameter_m,state (world;
  boll_id and state as ``farm.bolls.BollField``: ON_PLANT, HELD or IN_BIN);
* ``lanes.csv``   lane,x_m,y_start_m,y_end_m (world);
* ``route_world.csv`` / ``route_home.csv``  label,x_m,y_m,yaw_rad;
* ``route_gps.txt``  one "lat lon" line per waypoint (hector convention);
* ``farm.json``   all of the above plus the farm config ("bolls": one entry per
  boll with the columns of bolls.csv).

Maps are written with :func:`cottonsim_common.map_files.save_map` (map_server
conventions, described there); grids in memory follow nav_msgs/OccupancyGrid.
"""
from __future__ import annotations

import csv
import json
import math
import os
from dataclasses import dataclass
from typing import Dict, Optional

import numpy as np

from cottonsim_common.map_files import MapSaverConfig, save_map
from cottonsim_common.map_files import load_map_yaml  # noqa: F401  (re-export for scripts/kidnap_relocalization_sim.py)
from cottonsim_common.pose import Pose2D, world_to_frame
from cottonsim_common.transforms import quaternion_to_matrix
from cottonsim_world.farm.bolls import BollField
from cottonsim_world.farm.model import Farm, Primitive
from cottonsim_world.geodesy import HectorGeodesy

@dataclass(frozen=True)
class OccupancyMapConfig:
    """How the ground-truth occupancy map is rasterised.

    resolution_m: cell size [m/cell] (map_server default of the original 0.05).
    z_min_m, z_max_m: height band sliced through the collision primitives [m].
    z_samples: heights tested in the band (>= 1; evenly spaced, ends included).
    margin_m: free border around the plants, the route and the spawn [m].
    occupied_thresh, free_thresh: written to the YAML (map_server semantics).
    """

    resolution_m: float = 0.05
    z_min_m: float = 0.3
    z_max_m: float = 0.5
    z_samples: int = 5
    margin_m: float = 3.0
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196

    def __post_init__(self) -> None:
        if not (math.isfinite(self.resolution_m) and 0.005 <= self.resolution_m <= 1.0):
            raise ValueError(f"resolution_m must be in [0.005, 1.0], got {self.resolution_m}")
        if not (math.isfinite(self.z_min_m) and math.isfinite(self.z_max_m) and 0.0 <= self.z_min_m <= self.z_max_m):
            raise ValueError(f"z_min_m/z_max_m must satisfy 0 <= z_min_m <= z_max_m, got {self.z_min_m}, {self.z_max_m}")
        if isinstance(self.z_samples, bool) or not isinstance(self.z_samples, int) or not 1 <= self.z_samples <= 50:
            raise ValueError(f"z_samples must be an integer in [1, 50], got {self.z_samples!r}")
        if not (math.isfinite(self.margin_m) and 0.0 <= self.margin_m <= 100.0):
            raise ValueError(f"margin_m must be in [0, 100], got {self.margin_m}")
        if not 0.0 < self.free_thresh < self.occupied_thresh < 1.0:
            raise ValueError(f"need 0 < free_thresh < occupied_thresh < 1, got {self.free_thresh}, {self.occupied_thresh}")


# ---------------------------------------------------------------- occupancy
def _inside(prim: Primitive, q: np.ndarray) -> np.ndarray:
    """Points q (N, 3) in the primitive's own frame: inside mask (N,)."""
    if prim.shape == "box":
        hx, hy, hz = prim.size[:3]
        return (np.abs(q[:, 0]) <= hx) & (np.abs(q[:, 1]) <= hy) & (np.abs(q[:, 2]) <= hz)
    if prim.shape == "cylinder":
        r, length = prim.size[:2]
        return (np.hypot(q[:, 0], q[:, 1]) <= r) & (np.abs(q[:, 2]) <= 0.5 * length)
    if prim.shape == "capsule":
        r, length = prim.size[:2]
        zc = np.clip(q[:, 2], -0.5 * length, 0.5 * length)
        return np.hypot(np.hypot(q[:, 0], q[:, 1]), q[:, 2] - zc) <= r
    if prim.shape == "sphere":
        return np.linalg.norm(q, axis=1) <= prim.size[0]
    raise ValueError(f"unknown primitive shape {prim.shape!r} (expected box, cylinder, capsule or sphere)")


def _bounding_radius(prim: Primitive) -> float:
    if prim.shape == "box":
        return float(np.linalg.norm(prim.size[:3]))
    if prim.shape in ("cylinder", "capsule"):
        r, length = prim.size[:2]
        return float(math.hypot(r, 0.5 * length) + (r if prim.shape == "capsule" else 0.0))
    if prim.shape == "sphere":
        return float(prim.size[0])
    raise ValueError(f"unknown primitive shape {prim.shape!r} (expected box, cylinder, capsule or sphere)")


def rasterize_occupancy(farm: Farm, config: OccupancyMapConfig = OccupancyMapConfig(),
                        frame: Optional[Pose2D] = None):
    """Occupancy of the plants' collision primitives in a height band.

    frame: the map frame as a pose in the world (None = world). The grid is
    axis-aligned in that frame and covers plants, route and spawn plus
    ``config.margin_m``; every cell not hit is free (this is ground truth).
    Returns (grid int8 [iy, ix] with 0 / 100, resolution_m, origin (x, y, yaw)).
    """
    frame = frame or Pose2D(0.0, 0.0, 0.0)
    res = config.resolution_m
    # extent: plants (with canopy), route, spawn, in the map frame
    pts = [farm.plant_positions()]
    pts.append(np.array([[p.x_m, p.y_m] for p in farm.route]).reshape(-1, 2))
    pts.append(np.array([[farm.spawn.x_m, farm.spawn.y_m]]))
    xy = np.concatenate(pts)
    fx, fy = world_to_frame(frame, xy[:, 0], xy[:, 1])
    reach = max((max(p.model.width_m, 2 * max((_bounding_radius(q) for q in p.model.collision), default=0))
                 for p in farm.plants), default=0.0) / 2.0
    pad = config.margin_m + reach
    x0 = math.floor((fx.min() - pad) / res) * res
    y0 = math.floor((fy.min() - pad) / res) * res
    nx = int(math.ceil((fx.max() + pad - x0) / res))
    ny = int(math.ceil((fy.max() + pad - y0) / res))
    grid = np.zeros((ny, nx), dtype=np.int8)
    zs = np.linspace(config.z_min_m, config.z_max_m, config.z_samples)
    c_f, s_f = math.cos(frame.yaw_rad), math.sin(frame.yaw_rad)

    for plant in farm.plants:
        c_p, s_p = math.cos(plant.yaw_rad), math.sin(plant.yaw_rad)
        for prim in plant.model.collision:
            rot = quaternion_to_matrix(prim.orientation)
            px, py, pz = prim.position
            # primitive centre in world, then in the map frame
            cxw = plant.x_m + c_p * px - s_p * py
            cyw = plant.y_m + s_p * px + c_p * py
            if pz + _bounding_radius(prim) < config.z_min_m or pz - _bounding_radius(prim) > config.z_max_m:
                continue
            cxf, cyf = world_to_frame(frame, cxw, cyw)
            br = _bounding_radius(prim)
            ix0 = max(int(math.floor((cxf - br - x0) / res)), 0)
            ix1 = min(int(math.ceil((cxf + br - x0) / res)), nx)
            iy0 = max(int(math.floor((cyf - br - y0) / res)), 0)
            iy1 = min(int(math.ceil((cyf + br - y0) / res)), ny)
            if ix0 >= ix1 or iy0 >= iy1:
                continue
            gx, gy = np.meshgrid(x0 + (np.arange(ix0, ix1) + 0.5) * res, y0 + (np.arange(iy0, iy1) + 0.5) * res)
            wx = frame.x_m + c_f * gx - s_f * gy                 # cell centres in world
            wy = frame.y_m + s_f * gx + c_f * gy
            # world -> plant-local -> primitive frame
            dx, dy = wx.ravel() - plant.x_m, wy.ravel() - plant.y_m
            lx, ly = c_p * dx + s_p * dy - px, -s_p * dx + c_p * dy - py
            hit = np.zeros(lx.shape, dtype=bool)
            for z in zs:
                local = np.stack([lx, ly, np.full_like(lx, z - pz)], axis=1) @ rot   # R^T q, row form
                hit |= _inside(prim, local)
            sub = grid[iy0:iy1, ix0:ix1]
            sub[hit.reshape(sub.shape)] = 100
    return grid, res, (float(x0), float(y0), 0.0)


# -------------------------------------------------------------- tabular data
def write_plants_csv(path: str, farm: Farm) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["plant_id", "row", "index", "x_m", "y_m", "yaw_rad", "height_m"])
        for p in farm.plants:
            w.writerow([p.plant_id, p.row, p.index_in_row, f"{p.x_m:.4f}", f"{p.y_m:.4f}",
                        f"{p.yaw_rad:.5f}", f"{p.model.height_m:.4f}"])


def boll_rows(farm: Farm, field: Optional[BollField] = None) -> List[Dict]:
    """One dict per boll (the columns of bolls.csv), from ``field`` (default: the farm's bolls, all on their
    plants)."""
    field = field if field is not None else BollField(farm)
    return [{"boll_id": b.boll_id, "plant_id": b.plant_id, "boll": b.index_on_plant,
             "x_m": round(b.position_m[0], 5), "y_m": round(b.position_m[1], 5), "z_m": round(b.position_m[2], 5),
             "radius_m": round(b.diameter_m / 2.0, 5), "diameter_m": round(b.diameter_m, 5), "state": b.state.name}
            for b in field.all()]


def write_bolls_csv(path: str, farm: Farm, field: Optional[BollField] = None) -> None:
    """bolls.csv (module docstring) of ``field`` (default: the farm's bolls, all on their plants)."""
    rows = boll_rows(farm, field)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["boll_id", "plant_id", "boll", "x_m", "y_m", "z_m", "radius_m", "diameter_m", "state"])
        for r in rows:
            w.writerow([r["boll_id"], r["plant_id"], r["boll"], f"{r['x_m']:.4f}", f"{r['y_m']:.4f}",
                        f"{r['z_m']:.4f}", f"{r['radius_m']:.4f}", f"{r['diameter_m']:.4f}", r["state"]])


def write_lanes_csv(path: str, farm: Farm) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["lane", "x_m", "y_start_m", "y_end_m"])
        for lane in farm.lanes:
            w.writerow([lane.index, f"{lane.x_m:.4f}", f"{lane.y_start_m:.4f}", f"{lane.y_end_m:.4f}"])


def route_in_frame(farm: Farm, frame: Optional[Pose2D] = None) -> np.ndarray:
    """Route as (N, 3) x, y, yaw in ``frame`` (None = world)."""
    r = np.array([[p.x_m, p.y_m, p.yaw_rad] for p in farm.route], dtype=float).reshape(-1, 3)
    if frame is None or len(r) == 0:
        return r
    return np.stack(world_to_frame(frame, r[:, 0], r[:, 1], r[:, 2]), axis=1)


def write_route_csv(path: str, farm: Farm, frame: Optional[Pose2D] = None) -> None:
    """label,x_m,y_m,yaw_rad of the default route in ``frame`` (None = world)."""
    r = route_in_frame(farm, frame)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["label", "x_m", "y_m", "yaw_rad"])
        for label, (x, y, yaw) in zip(farm.route_labels, r):
            w.writerow([label, f"{x:.4f}", f"{y:.4f}", f"{yaw:.6f}"])


def write_route_gps(path: str, farm: Farm, geodesy: Optional[HectorGeodesy] = None) -> None:
    """One "lat lon" line per route waypoint, like the original's waypoint file."""
    geodesy = geodesy or HectorGeodesy()
    r = route_in_frame(farm)
    lat, lon, _ = geodesy.world_to_geodetic(r[:, 0], r[:, 1], np.zeros(len(r)))
    with open(path, "w") as fh:
        for a, b in zip(lat, lon):
            fh.write(f"{a:.14f} {b:.14f}\n")


def farm_to_dict(farm: Farm, geodesy: Optional[HectorGeodesy] = None) -> Dict:
    """Everything about the farm as plain JSON-able data (world frame)."""
    geodesy = geodesy or HectorGeodesy()
    cfg = farm.config.to_dict() if hasattr(farm.config, "to_dict") else {}
    r = route_in_frame(farm)
    home = route_in_frame(farm, farm.spawn)
    lat, lon, _ = geodesy.world_to_geodetic(r[:, 0], r[:, 1], np.zeros(len(r)))
    return {
        "config": cfg,
        "spawn": {"x_m": farm.spawn.x_m, "y_m": farm.spawn.y_m, "yaw_rad": farm.spawn.yaw_rad},
        "lanes": [{"lane": l.index, "x_m": l.x_m, "y_start_m": l.y_start_m, "y_end_m": l.y_end_m} for l in farm.lanes],
        "route": [{"label": lab, "x_m": float(a[0]), "y_m": float(a[1]), "yaw_rad": float(a[2]),
                   "home_x_m": float(h[0]), "home_y_m": float(h[1]), "home_yaw_rad": float(h[2]),
                   "lat_deg": float(la), "lon_deg": float(lo)}
                  for lab, a, h, la, lo in zip(farm.route_labels, r, home, lat, lon)],
        "plants": [{"plant_id": p.plant_id, "row": p.row, "index": p.index_in_row, "x_m": p.x_m, "y_m": p.y_m,
                    "yaw_rad": p.yaw_rad, "height_m": p.model.height_m,
                    "bolls": [[round(float(v), 5) for v in c] + [round(float(rad), 5)]
                              for c, rad in zip(p.boll_centres_world(), p.model.boll_radii)]}
                   for p in farm.plants],
        "bolls": boll_rows(farm),
    }


def export_all(farm: Farm, out_dir: str, geodesy: Optional[HectorGeodesy] = None,
               map_config: OccupancyMapConfig = OccupancyMapConfig()) -> Dict[str, str]:
    """Write every export (see the module docstring); returns name -> path."""
    os.makedirs(out_dir, exist_ok=True)
    geodesy = geodesy or HectorGeodesy()
    paths: Dict[str, str] = {}
    for name, frame in (("map_world", None), ("map_home", farm.spawn)):
        grid, res, origin = rasterize_occupancy(farm, map_config, frame)
        thresholds = MapSaverConfig(occupied_thresh=100.0 * map_config.occupied_thresh,
                                    free_thresh=100.0 * map_config.free_thresh)
        _, paths[name] = save_map(os.path.join(out_dir, name), grid, res, origin, thresholds,
                                  creator="cottonsim ground truth")
    for name, fn in (("plants", write_plants_csv), ("bolls", write_bolls_csv), ("lanes", write_lanes_csv)):
        paths[name] = os.path.join(out_dir, name + ".csv")
        fn(paths[name], farm)
    paths["route_world"] = os.path.join(out_dir, "route_world.csv")
    write_route_csv(paths["route_world"], farm)
    paths["route_home"] = os.path.join(out_dir, "route_home.csv")
    write_route_csv(paths["route_home"], farm, farm.spawn)
    paths["route_gps"] = os.path.join(out_dir, "route_gps.txt")
    write_route_gps(paths["route_gps"], farm, geodesy)
    paths["farm_json"] = os.path.join(out_dir, "farm.json")
    with open(paths["farm_json"], "w") as fh:
        json.dump(farm_to_dict(farm, geodesy), fh, indent=1)
    return paths
