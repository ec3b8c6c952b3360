"""Where the robot stands for one image: random robot poses and the cameras' mounting.

``sample_robot_pose`` puts the robot in a lane or at a headland (scene
segmentation images, front camera) or beside / in front of plants (boll
detection images, side or front camera); ``camera_transforms`` reads the
base_link -> camera optical frame transforms from the robot's URDF. Frames:
world (z up, ground z = 0) as in ``farm.model``; optical frames as in
``sensors.camera`` (z forward, x right, y down). No ROS imports.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict

import numpy as np

from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.model import Farm
from cottonsim_world.physics.husky_params import HuskyParams

from .config import CAMERA_FRONT, CAMERA_LEFT, CAMERA_RIGHT, CAMERAS, TASKS, VariationConfig


def _clipped_normal(rng: np.random.Generator, std: float) -> float:
    return float(np.clip(rng.normal(0.0, std), -2.5 * std, 2.5 * std)) if std > 0 else 0.0


def base_pose_matrix(x_m: float, y_m: float, yaw_rad: float, z_m: float,
                     roll_rad: float = 0.0, pitch_rad: float = 0.0) -> np.ndarray:
    """world_T_base: translation (x, y, z) and rotation Rz(yaw) Ry(pitch) Rx(roll)."""
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    out = np.eye(4)
    out[:3, :3] = rz @ ry @ rx
    out[:3, 3] = (x_m, y_m, z_m)
    return out


@dataclass(frozen=True)
class RobotShot:
    """Where one image is taken from: the camera and the robot's base pose."""

    camera: str
    mode: str                   # 'lane', 'headland', 'side', 'close'
    world_T_base: np.ndarray    # 4x4


def _clear_of_plants(farm: Farm, points_xy: np.ndarray, margin_m: float) -> bool:
    """True when every point is farther than half a plant width + margin from every stem."""
    stems = farm.plant_positions()
    if len(stems) == 0:
        return True
    width = max((p.model.width_m for p in farm.plants), default=0.7)
    d = np.linalg.norm(points_xy[:, None, :] - stems[None, :, :], axis=2)
    return bool(np.all(d > 0.5 * width + margin_m))


def sample_robot_pose(farm: Farm, task: str, rng: np.random.Generator, variation: VariationConfig,
                      base_T_optical: Dict[str, np.ndarray], base_height_m: float = HuskyParams().base_link_height_m,
                      max_tries: int = 30) -> RobotShot:
    """A random robot pose for one image of ``task`` (see the module docstring).

    seg: 'lane' (in a lane, heading along it, offset and yaw noise) or
    'headland' (beyond a row end, turning); camera realsense_p.
    det: 'side' (in a lane next to a row, the secondary or tertiary camera
    facing the row) or 'close' (the front camera 0.55-1.1 m from one plant,
    looking at it roughly across the row).
    Poses whose camera or base centre would be inside a plant's canopy are
    redrawn (up to ``max_tries``; then the last draw is used).
    """
    if task not in TASKS:
        raise ValueError(f"task must be one of {TASKS}, got {task!r}")
    cfg = farm.config if isinstance(farm.config, FarmConfig) else FarmConfig()
    v = variation
    lanes = farm.lanes
    if not lanes:
        raise ValueError("farm has no lanes: cannot place the robot")
    y_lo = min(l.y_start_m for l in lanes)
    y_hi = max(l.y_end_m for l in lanes)
    x_lanes = np.array([l.x_m for l in lanes])
    shot = None
    for _ in range(max_tries):
        roll = _clipped_normal(rng, v.camera_roll_std_rad)
        pitch = _clipped_normal(rng, v.camera_pitch_std_rad)
        z = base_height_m + _clipped_normal(rng, v.camera_height_std_m)
        if task == "seg":
            camera = CAMERA_FRONT
            if rng.random() < v.headland_probability:
                mode = "headland"
                south = rng.random() < 0.5
                dist = rng.uniform(*v.headland_distance_range_m)
                y = y_lo - dist if south else y_hi + dist
                x = rng.uniform(x_lanes.min() - 1.0, x_lanes.max() + 1.0)
                into_rows = math.pi / 2 if south else -math.pi / 2
                yaw = into_rows + rng.uniform(-v.headland_yaw_max_rad, v.headland_yaw_max_rad)
            else:
                mode = "lane"
                lane = lanes[int(rng.integers(len(lanes)))]
                x = lane.x_m + _clipped_normal(rng, v.lane_offset_std_m)
                y = rng.uniform(y_lo - 2.5, y_hi + 1.0)
                north = rng.random() < 0.5
                if not north:
                    y = y_lo + y_hi - y          # mirror: heading south starts at the north end
                yaw = (math.pi / 2 if north else -math.pi / 2) + _clipped_normal(rng, v.yaw_std_rad)
        else:
            plants = farm.plants
            if not plants:
                raise ValueError("farm has no plants: cannot take boll detection images")
            if rng.random() < v.front_close_probability:
                mode, camera = "close", CAMERA_FRONT
                target = plants[int(rng.integers(len(plants)))]
                across = 0.0 if rng.random() < 0.5 else math.pi        # look towards +x or -x
                view = across + rng.uniform(-v.close_yaw_max_rad, v.close_yaw_max_rad)
                d = rng.uniform(*v.close_distance_range_m)
                cam_xy = np.array([target.x_m, target.y_m]) - d * np.array([math.cos(view), math.sin(view)])
                yaw = view + _clipped_normal(rng, v.yaw_std_rad)
                offset = base_T_optical[camera][:2, 3]
                c, s = math.cos(yaw), math.sin(yaw)
                x = cam_xy[0] - (c * offset[0] - s * offset[1])
                y = cam_xy[1] - (s * offset[0] + c * offset[1])
            else:
                mode = "side"
                camera = CAMERA_LEFT if rng.random() < 0.5 else CAMERA_RIGHT
                row = int(rng.integers(cfg.rows))
                row_x = cfg.row_x_m(row)
                east = rng.random() < 0.5                   # the lane east (+x) or west of the row
                x = row_x + (0.5 if east else -0.5) * cfg.row_spacing_m + _clipped_normal(rng, v.lane_offset_std_m)
                y = rng.uniform(cfg.first_plant_y_m - 0.3, cfg.last_plant_y_m + 0.3)
                towards = math.pi if east else 0.0           # direction from the camera to the row
                # the camera's horizontal viewing direction in base_link
                axis = base_T_optical[camera][:3, 2]
                cam_dir = math.atan2(axis[1], axis[0])
                yaw = towards - cam_dir + _clipped_normal(rng, v.yaw_std_rad)
        base = base_pose_matrix(x, y, yaw, z, roll, pitch)
        cam = base @ base_T_optical[camera]
        shot = RobotShot(camera, mode, base)
        if _clear_of_plants(farm, np.array([cam[:2, 3], base[:2, 3]]), 0.05):
            break
    return shot


def camera_transforms(urdf_path: str) -> Dict[str, np.ndarray]:
    """base_T_optical of each camera in ``CAMERAS``: base_link -> <camera>_color_optical_frame (4x4)."""
    from cottonsim_world.robot.urdf_model import UrdfModel
    urdf = UrdfModel.from_file(urdf_path)
    return {cam: urdf.fixed_transform("base_link", f"{cam}_color_optical_frame") for cam in CAMERAS}
