"""The readings ``Simulator.step()`` returns: plain dataclasses, one per sensor message the bridge publishes."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Optional

import numpy as np

from cottonsim_world.faults import GPS_STATUS_FIX
from cottonsim_world.physics.imu_model import ImuMeasurement
from cottonsim_world.physics.physics_config import ContactEvent, RobotState
from cottonsim_world.physics.wheel_odometry import OdometryEstimate
from cottonsim_world.robot.arm_contacts import ArmContactEvent
from cottonsim_world.sensors.camera import CameraFrame, CameraIntrinsics
from cottonsim_world.sensors.cloud_filters import LaserScanConfig
from cottonsim_world.sensors.lidar import LidarScan


@dataclass
class CameraReading:
    stamp_s: float
    camera: str
    frame_id: str
    frame: CameraFrame
    intrinsics: CameraIntrinsics
    cloud_xyz: Optional[np.ndarray] = None   # (N, 3) float32 in the optical frame, when wanted
    cloud_rgb: Optional[np.ndarray] = None   # (N, 3) uint8
    # the same cloud in PointCloud2's layout: (N, 4) float32 x, y, z, packed 0x00RRGGBB bits
    # (CameraModel.point_cloud_xyzrgb); cloud_xyz is a view of it
    cloud_xyzrgb: Optional[np.ndarray] = None


@dataclass
class LidarReading:
    stamp_s: float
    frame_id: str
    scan: LidarScan
    passthrough_points: np.ndarray           # (M, 3) float32, the paper's PassThrough filter
    scan_ranges: np.ndarray                  # LaserScan ranges (inf = no return)
    scan_config: LaserScanConfig
    scan_360_ranges: np.ndarray              # the full-circle scan
    scan_360_config: LaserScanConfig


@dataclass
class ImuReading:
    stamp_s: float
    frame_id: str
    measurement: ImuMeasurement


@dataclass
class GpsReading:
    stamp_s: float
    frame_id: str
    latitude_deg: float
    longitude_deg: float
    altitude_m: float
    position_variance_m2: float       # per axis [m^2]; NaN when unknown (no fix)
    status: int = GPS_STATUS_FIX      # NavSatStatus: -1 no fix, 0 fix, 1 SBAS, 2 GBAS (faults change it)


@dataclass
class OdometryReading:
    stamp_s: float
    wheel: OdometryEstimate
    filtered: OdometryEstimate


@dataclass
class JointStatesReading:
    stamp_s: float
    names: List[str]
    positions: np.ndarray
    velocities: np.ndarray


@dataclass
class GroundTruthReading:
    stamp_s: float
    state: RobotState


@dataclass
class ContactsReading:
    stamp_s: float
    events: List[ContactEvent]
    total_contact_events: int
    plants_touched: List[int]


@dataclass
class ArmContactsReading:
    """Arm-plant contact events since the last reading, the running totals per kind ('stem', 'leaf')
    and the plants the arm has touched (robot/arm_contacts.py)."""
    stamp_s: float
    events: List[ArmContactEvent]
    totals: Dict[str, int]
    plants_touched: List[int]
