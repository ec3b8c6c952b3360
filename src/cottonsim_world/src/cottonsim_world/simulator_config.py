"""What defines a simulated run: ``SimulatorConfig``, and the names of the robot's frames and joints.

Read from config/sim.yaml by ``config_io.simulator_config_from_dict``; the
``Simulator`` (``simulator.py``) builds the world from it.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from cottonsim_world.estimation.odometry_ekf import OdometryEkfConfig
from cottonsim_world.farm.bolls import BollFieldConfig
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.faults import FaultScheduleConfig
from cottonsim_world.geodesy import GpsNoiseConfig
from cottonsim_world.physics.husky_params import DriveLimits, HuskyParams
from cottonsim_world.physics.imu_model import ImuConfig
from cottonsim_world.physics.physics_config import PhysicsConfig
from cottonsim_world.robot.arm_contacts import ArmContactConfig
from cottonsim_world.robot.arm_tracker import ArmControllerConfig
from cottonsim_world.robot.ur5e import JOINT_NAMES as ARM_JOINTS
from cottonsim_world.robot.vacuum import VacuumConfig
from cottonsim_world.sensors.camera import CameraConfig
from cottonsim_world.sensors.cloud_filters import LaserScanConfig, PassThroughConfig
from cottonsim_world.sensors.lidar import LidarConfig
from cottonsim_world.sensors.scene import SceneConfig

CAMERA_NAMES = ("realsense_p", "realsense_secondary", "realsense_tertiary")
WHEEL_JOINTS = ("front_left_wheel_joint", "front_right_wheel_joint", "rear_left_wheel_joint",
                "rear_right_wheel_joint")
ARM_PREFIX = "ur5e_"
ARM_JOINT_NAMES = tuple(ARM_PREFIX + name for name in ARM_JOINTS)
ARM_PERIOD_S = 0.01          # the UR5e's position follower (/arm_controller/command) runs at 100 Hz
MAX_SENSOR_WORKERS = 8      # upper bound of SimulatorConfig.sensor_workers
LIDAR_FRAME = "velodyne"
IMU_FRAME = "imu_link"
BASE_FRAME = "base_link"


def optical_frame(camera: str) -> str:
    return f"{camera}_color_optical_frame"


def _positive_rate(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ValueError(f"SimulatorConfig.{name} must be a rate > 0 [Hz], got {value!r}")


@dataclass(frozen=True)
class SimulatorConfig:
    """Everything that defines a simulated run.

    cameras: (namespace, CameraConfig) pairs; namespaces must have a
    ``<ns>_color_optical_frame`` in the URDF. ``camera_enabled`` /
    ``lidar_enabled`` remove a sensor entirely (not built, never rendered).
    Rates are in sim-time Hz. ``seed`` seeds every random process (physics
    solver order, IMU, GPS, LiDAR and camera noise); the sub-configs' own
    seeds are replaced by values derived from it.

    sensor_workers: worker threads [-] that render the cameras and scan the
    LiDAR while the main thread steps the physics (the module docstring);
    0 (default) = serial, everything inside ``step()``. 1 overlaps the
    sensors with the physics; more than 1 also runs different sensors at
    once (the sensor models must then not share mutable state, so the
    pybullet renderers / LiDAR backend need <= 1). The
    readings are the same either way; only their return is later (at most
    one sensor period of sim time).
    faults: scheduled sensor faults (``cottonsim_world.faults``; default none); a
    camera_blackout must name a camera of ``cameras`` (or 'all').
    bolls: rules of the boll field (``farm.bolls.BollFieldConfig``).
    arm_contacts: the arm-plant contact counter (``robot.arm_contacts.ArmContactConfig``);
    its readings go out at ``contacts_rate_hz`` with the base's plant contacts.
    sensor_switch_interval_s: Python's GIL switch interval [s]
    (``sys.setswitchinterval``, Python's default 0.005) while pipelined,
    restored by ``close()``; 0 (default) = leave it. A sensor job coming
    out of a GIL-free kernel needs the GIL back and may wait up to this
    long while the physics thread runs Python (the convoy effect). Measured
    on the shared vm: no difference between 5 and 0.5 ms (the physics step
    releases the GIL in its ctypes call every step; a job starts ~1.3 ms
    after its submission either way), hence left as Python has it.
    Unused when serial.
    """

    farm: FarmConfig = FarmConfig()
    physics: PhysicsConfig = PhysicsConfig()
    husky: HuskyParams = HuskyParams()
    drive_limits: DriveLimits = DriveLimits()
    scene: SceneConfig = SceneConfig()
    cameras: Tuple[Tuple[str, CameraConfig], ...] = tuple((name, CameraConfig()) for name in CAMERA_NAMES)
    lidar: LidarConfig = LidarConfig()
    lidar_enabled: bool = True
    laserscan: LaserScanConfig = LaserScanConfig()
    # A full-circle scan from the same cloud, for SLAM and AMCL (the original's +/-45 deg
    # forward sector leaves the particle filters ill-conditioned along crop rows). Its slice
    # reaches 0.25 m below the sensor (still 0.13 m above the ground at the VLP-16's 0.38 m
    # height): the original's 0.0-0.1 m slice holds only the +1 deg ring, which leaves it
    # beyond 5.7 m; the -1 and -3 deg rings add plant returns out to ~14 m.
    laserscan_360: LaserScanConfig = LaserScanConfig(min_height_m=-0.25, angle_min_rad=-math.pi,
                                                     angle_max_rad=math.pi - 0.0087)
    passthrough: PassThroughConfig = PassThroughConfig()
    imu: ImuConfig = ImuConfig()
    gps_noise: GpsNoiseConfig = GpsNoiseConfig()
    gps_rate_hz: float = 40.0
    geodesy_reference: Tuple[float, float, float, float] = (49.9, 8.9, 0.0, 0.0)  # lat, lon [deg], alt [m], heading [deg]
    odometry_rate_hz: float = 50.0
    ekf: OdometryEkfConfig = OdometryEkfConfig()
    joint_states_rate_hz: float = 50.0
    ground_truth_rate_hz: float = 50.0
    contacts_rate_hz: float = 10.0
    arm_initial_positions_rad: Tuple[float, ...] = (0.0, -2.2, 2.4, -1.77, -1.57, 0.0)   # stowed over the base
    arm_controller: ArmControllerConfig = ArmControllerConfig()
    vacuum: VacuumConfig = VacuumConfig()
    seed: int = 0
    sensor_workers: int = 0
    sensor_switch_interval_s: float = 0.0
    faults: FaultScheduleConfig = FaultScheduleConfig()
    bolls: BollFieldConfig = BollFieldConfig()
    arm_contacts: ArmContactConfig = ArmContactConfig()

    def __post_init__(self):
        if (not isinstance(self.sensor_workers, int) or isinstance(self.sensor_workers, bool)
                or not 0 <= self.sensor_workers <= MAX_SENSOR_WORKERS):
            raise ValueError(f"SimulatorConfig.sensor_workers must be an int in 0..{MAX_SENSOR_WORKERS} "
                             f"(0 = serial), got {self.sensor_workers!r}")
        v = self.sensor_switch_interval_s
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (0.0 <= v <= 0.1):
            raise ValueError(f"SimulatorConfig.sensor_switch_interval_s must be a number of seconds in "
                             f"[0, 0.1] (0 = leave Python's), got {v!r}")
        for name in ("gps_rate_hz", "odometry_rate_hz", "joint_states_rate_hz", "ground_truth_rate_hz",
                     "contacts_rate_hz"):
            _positive_rate(name, getattr(self, name))
        names = [name for name, _ in self.cameras]
        if len(set(names)) != len(names):
            raise ValueError(f"SimulatorConfig.cameras has duplicate names: {names}")
        for name, cam in self.cameras:
            if not isinstance(cam, CameraConfig):
                raise ValueError(f"SimulatorConfig.cameras['{name}'] must be a CameraConfig")
        if self.sensor_workers > 1:
            pybullet_users = [f"cameras['{name}'] (renderer {cam.renderer!r})" for name, cam in self.cameras
                              if cam.renderer != "numba"]
            if self.lidar_enabled and self.lidar.backend != "numba":
                pybullet_users.append(f"lidar (backend {self.lidar.backend!r})")
            if pybullet_users:
                raise ValueError(f"SimulatorConfig.sensor_workers > 1 runs sensors at the same time, which the "
                                 f"pybullet backends do not allow; use the numba ones or 1 worker: "
                                 f"{', '.join(pybullet_users)}")
        if len(self.arm_initial_positions_rad) != 6:
            raise ValueError("SimulatorConfig.arm_initial_positions_rad needs 6 joint angles [rad]")
        if not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"SimulatorConfig.seed must be an int >= 0, got {self.seed!r}")
        if not isinstance(self.faults, FaultScheduleConfig):
            raise ValueError(f"SimulatorConfig.faults must be a FaultScheduleConfig, got {type(self.faults).__name__}")
        self.faults.check_cameras(names)

    def with_seed_applied(self) -> "SimulatorConfig":
        """A copy whose noise models carry seeds derived from ``seed``."""
        seeds = np.random.SeedSequence(self.seed).generate_state(8)
        cameras = tuple((name, dataclasses.replace(cam, seed=int(seeds[5]) + i))
                        for i, (name, cam) in enumerate(self.cameras))
        return dataclasses.replace(
            self,
            physics=dataclasses.replace(self.physics, seed=int(seeds[0])),
            imu=dataclasses.replace(self.imu, seed=int(seeds[1])),
            gps_noise=dataclasses.replace(self.gps_noise, seed=int(seeds[2])),
            lidar=dataclasses.replace(self.lidar, seed=int(seeds[3])),
            cameras=cameras,
            faults=dataclasses.replace(self.faults, seed=int(seeds[6])))
