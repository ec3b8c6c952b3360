"""The whole simulated world, stepped in-process without ROS.

``Simulator`` owns the farm, the ODE dynamics of the Husky, the pybullet
sensor scene, the sensor and noise models, the wheel odometry with the
Husky's EKF and the UR5e arm with its trajectory controller and vacuum
nozzle (``arm_system``, robot/sim_arm.py). Each ``step()`` advances the physics by one
step and returns the sensor readings that fell due, as plain dataclasses;
the ROS bridge (``ros/bridge_node.py``) only converts and publishes them, and
scripts, benchmarks and tests can drive the same object directly::

    sim = Simulator(SimulatorConfig(), UrdfModel.from_file(urdf_path))
    sim.command_velocity(0.5, 0.0)
    while sim.time_s < 10.0:
        for reading in sim.step():
            ...

Given the same config (including its seed) and the same command sequence,
a run is deterministic: ODE's solver is seeded and every noise model has a
seed derived from ``SimulatorConfig.seed``.

Pipelined sensors (``sensor_workers`` > 0), the sensor frames from the URDF, switching sensors off,
sensor faults and the bolls' visibility: docs/simulator.md.
"""
from __future__ import annotations

import math
import sys
import time
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Callable, Deque, Dict, List, Optional, Sequence

import numpy as np

from cottonsim_common.rate_slots import FirstOfSlotGate
from cottonsim_common.transforms import pose_matrix
from cottonsim_world.estimation.odometry_ekf import OdometryEkf
from cottonsim_world.farm.bolls import BollField
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.farm.model import Farm, Pose2D
from cottonsim_world.farm.plant_obstacles import PlantObstacles
from cottonsim_world.faults import FaultInjector
from cottonsim_world.geodesy import GpsNoiseModel, HectorGeodesy
from cottonsim_world.physics.imu_model import ImuModel
from cottonsim_world.physics.imu_mount import ImuMount
from cottonsim_world.physics.ode_world import OdeWorld
from cottonsim_world.physics.physics_config import ContactEvent, RobotState
from cottonsim_world.physics.wheel_odometry import WheelOdometry, WheelOdometryConfig
from cottonsim_world.robot.arm_contacts import ArmContactCounter
from cottonsim_world.robot.boll_store import BollFieldStore
from cottonsim_world.robot.sim_arm import SimulatedArm
from cottonsim_world.robot.urdf_model import UrdfModel
from cottonsim_world.sensors.camera import CameraModel
from cottonsim_world.sensors.cloud_filters import cloud_to_laserscans, original_passthrough
from cottonsim_world.sensors.lidar import Vlp16Model
from cottonsim_world.sensors.scene import BollVisibility, SensorScene
from cottonsim_world.readings import (ArmContactsReading, CameraReading, ContactsReading, GpsReading,
                                      GroundTruthReading, ImuReading, JointStatesReading, LidarReading,
                                      OdometryReading)
from cottonsim_world.simulator_config import (ARM_JOINT_NAMES, ARM_PREFIX, BASE_FRAME, IMU_FRAME, LIDAR_FRAME,
                                              WHEEL_JOINTS, SimulatorConfig, optical_frame)
from cottonsim_world.sensor_schedule import HeldReading, Schedule, timed_job


class Simulator:
    """Steps farm, physics and sensors; see the module docstring."""

    def __init__(self, config: SimulatorConfig, urdf: UrdfModel, farm: Optional[Farm] = None):
        self.config = config.with_seed_applied()
        cfg = self.config
        self.urdf = urdf
        self.farm = farm if farm is not None else generate_farm(cfg.farm)

        self.physics = OdeWorld(cfg.physics, cfg.husky, cfg.drive_limits)
        self.physics.add_plants(self.farm.plants)
        self.physics.spawn_robot(self.farm.spawn)
        self.step_s = cfg.physics.step_s

        self.geodesy = HectorGeodesy(*cfg.geodesy_reference)
        self.faults = FaultInjector(cfg.faults, [name for name, _ in cfg.cameras], self.geodesy.radius_north_m,
                                    self.geodesy.radius_east_m)
        self.gps_noise = GpsNoiseModel(cfg.gps_noise)
        self._gps_variance_m2 = float(max(max(cfg.gps_noise.gaussian_noise_m), max(cfg.gps_noise.drift_m))) ** 2
        self.imu = ImuModel(cfg.imu)
        self.wheel_odometry = WheelOdometry(WheelOdometryConfig.from_husky(cfg.husky, cfg.drive_limits))
        self.ekf = OdometryEkf(cfg.ekf)
        # every boll with its state; the vacuum nozzle acts on it, the sensors hide what left the plants
        self.bolls = BollField(self.farm, cfg.bolls)
        # the arm counts its contacts with the plants' stems, branches and leaves
        self.arm_contacts = ArmContactCounter(PlantObstacles.from_farm(self.farm), cfg.arm_contacts)
        self.arm_system = SimulatedArm(urdf, ARM_PREFIX, cfg.arm_initial_positions_rad, cfg.arm_controller,
                                       cfg.vacuum, BollFieldStore(self.bolls), BASE_FRAME, self.arm_contacts)
        self.arm = self.arm_system.arm

        self.sensor_scene: Optional[SensorScene] = None
        self.cameras: Dict[str, CameraModel] = {}
        self.lidar: Optional[Vlp16Model] = None
        if cfg.cameras or cfg.lidar_enabled:
            self.sensor_scene = SensorScene(self.farm, cfg.scene)
        self.base_T_sensor: Dict[str, np.ndarray] = {}
        for name, cam_cfg in cfg.cameras:
            self.cameras[name] = CameraModel(self.sensor_scene, cam_cfg)
            self.base_T_sensor[name] = urdf.fixed_transform(BASE_FRAME, optical_frame(name))
        if cfg.lidar_enabled:
            self.lidar = Vlp16Model(self.sensor_scene, cfg.lidar)
            self.base_T_sensor[LIDAR_FRAME] = urdf.fixed_transform(BASE_FRAME, LIDAR_FRAME)
        self.base_T_sensor[IMU_FRAME] = urdf.fixed_transform(BASE_FRAME, IMU_FRAME)
        self.imu_mount = ImuMount(self.base_T_sensor[IMU_FRAME][:3, :3])
        self._joint_names = list(WHEEL_JOINTS) + list(ARM_JOINT_NAMES)

        self._schedules: Dict[str, Schedule] = {}
        for name, cam_cfg in cfg.cameras:
            self._schedules[name] = Schedule(name, 1.0 / cam_cfg.rate_hz)
        if cfg.lidar_enabled:
            self._schedules["lidar"] = Schedule("lidar", 1.0 / cfg.lidar.rate_hz)
        self._schedules["imu"] = Schedule("imu", 1.0 / cfg.imu.rate_hz)
        self._schedules["gps"] = Schedule("gps", 1.0 / cfg.gps_rate_hz)
        self._schedules["odometry"] = Schedule("odometry", 1.0 / cfg.odometry_rate_hz)
        self._schedules["joint_states"] = Schedule("joint_states", 1.0 / cfg.joint_states_rate_hz)
        self._schedules["ground_truth"] = Schedule("ground_truth", 1.0 / cfg.ground_truth_rate_hz)
        self._schedules["contacts"] = Schedule("contacts", 1.0 / cfg.contacts_rate_hz)
        if cfg.arm_contacts.enabled:
            self._schedules["arm_contacts"] = Schedule("arm_contacts", 1.0 / cfg.contacts_rate_hz)
        self._camera_cloud_wanted = {name: True for name, _ in cfg.cameras}
        # cameras rendered at a consumer's rate only (render_rate_hz > 0): the first frame of each slot
        self._render_gates = {name: FirstOfSlotGate(cam_cfg.render_rate_hz)
                              for name, cam_cfg in cfg.cameras if cam_cfg.render_rate_hz > 0.0}
        # sensor name -> (now, state) -> (function, args) of its reading: the part a worker can run
        self._jobs: Dict[str, Callable] = {name: (lambda now, state, name=name: self._camera_job(name, now, state))
                                           for name in self.cameras}
        if self.lidar is not None:
            self._jobs["lidar"] = self._lidar_job
        self._last_gps_s = 0.0
        self._last_odom_s = 0.0
        self._physics_wall_s = 0.0
        self._contacts: List[ContactEvent] = []
        self._next_due_s = 0.0      # earliest next_s of all schedules: steps before it skip the scan
        # pipelined sensors (sensor_workers > 0): the worker pool and the readings not yet returned
        self._workers: Optional[ThreadPoolExecutor] = None
        self._saved_switch_interval_s: Optional[float] = None     # Python's, while we changed it
        if cfg.sensor_workers > 0 and (self.cameras or self.lidar is not None):
            self._workers = ThreadPoolExecutor(max_workers=cfg.sensor_workers, thread_name_prefix="cottonsim-sensor")
            if cfg.sensor_switch_interval_s > 0.0:
                self._saved_switch_interval_s = sys.getswitchinterval()
                sys.setswitchinterval(cfg.sensor_switch_interval_s)
        self._held: Deque[HeldReading] = deque()
        self._last_job: Dict[str, Future] = {}  # each pipelined sensor's latest job
        self._held_deadline_s = math.inf    # earliest deadline of a pending job in _held
        self._delivered_s = 0.0             # stamp of the last reading returned
        self._sensor_wait_s = 0.0           # wall time step() / flush_readings() waited for jobs [s]

    # ------------------------------------------------------------------ inputs
    @property
    def time_s(self) -> float:
        return self.physics.sim_time_s

    def command_velocity(self, linear_x_m_s: float, angular_z_rad_s: float) -> Optional[str]:
        """A /cmd_vel command, stamped now; returns a reason if it was refused (NaN, inf)."""
        return self.physics.set_command(linear_x_m_s, angular_z_rad_s, self.time_s)

    def command_arm(self, positions_rad: Sequence[float]) -> np.ndarray:
        """UR5e joint position targets [rad]; clamped to the URDF limits (returned). Trajectory goals:
        ``arm_system`` (robot/sim_arm.py)."""
        return self.arm_system.command_positions(positions_rad)

    def teleport_robot(self, x_m: float, y_m: float, yaw_rad: float) -> None:
        """Move the robot (ground truth) to (x_m, y_m, yaw_rad) in the world frame, at rest: a kidnap.

        The Husky is re-spawned there (wheels stopped, the last /cmd_vel forgotten); wheel odometry
        and the EKF integrate wheel speeds only, so they do not see the jump. ValueError for a
        non-finite pose.
        """
        pose = (x_m, y_m, yaw_rad)
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in pose):
            raise ValueError(f"teleport pose (x_m, y_m, yaw_rad) must be 3 finite numbers, got {pose!r}")
        self.physics.spawn_robot(Pose2D(float(x_m), float(y_m), float(yaw_rad)))

    def set_sensor_active(self, name: str, active: bool) -> None:
        """Switch a sensor's updates on/off (e.g. nobody subscribes). Names: see ``sensor_names``."""
        if name not in self._schedules:
            raise ValueError(f"unknown sensor '{name}', known: {sorted(self._schedules)}")
        self._schedules[name].active = bool(active)

    def set_camera_cloud_wanted(self, camera: str, wanted: bool) -> None:
        """Whether a camera's depth point cloud is computed (it is the costly part of a reading)."""
        if camera not in self._camera_cloud_wanted:
            raise ValueError(f"unknown camera '{camera}', known: {sorted(self._camera_cloud_wanted)}")
        self._camera_cloud_wanted[camera] = bool(wanted)

    @property
    def sensor_names(self) -> List[str]:
        return list(self._schedules)

    def sensor_timing_ms(self) -> Dict[str, float]:
        """Mean wall time per update of each sensor so far [ms] (0 if never run; pipelined: once returned)."""
        return {s.name: (1e3 * s.wall_s / s.count if s.count else 0.0) for s in self._schedules.values()}

    def sensor_cpu_ms(self) -> Dict[str, float]:
        """Mean process CPU time per update of each sensor so far [ms], summed over threads (0 if never run).

        On a shared machine wall time includes waiting for a core; CPU time does not. Pipelined
        (``sensor_workers`` > 0): CPU time of the thread that made the reading only, the worker's
        for cameras / LiDAR (numba's own parallel threads not included), the main thread's for
        the others.
        """
        return {s.name: (1e3 * s.cpu_s / s.count if s.count else 0.0) for s in self._schedules.values()}

    @property
    def pipelined(self) -> bool:
        """Whether cameras and LiDAR run on worker threads (``SimulatorConfig.sensor_workers`` > 0)."""
        return self._workers is not None

    @property
    def delivered_time_s(self) -> float:
        """Sim time [s] up to which ``step()`` has returned every reading.

        Equals ``time_s`` when serial or when nothing is pending; with
        pipelined sensors it may lag ``time_s`` by up to one sensor period.
        No reading returned so far is stamped later, none returned later
        is stamped earlier: the bridge publishes it as /clock.
        """
        if not self._held:
            return self.time_s
        return max(self._delivered_s, self._held[0].before_s)

    @property
    def sensor_wait_s(self) -> float:
        """Wall time [s] the stepping thread has waited for pipelined sensor jobs so far (0 when serial).

        Near 0: the physics is the slower side; large: the sensor workers are.
        """
        return self._sensor_wait_s

    def physics_step_ms(self) -> float:
        steps = max(1, round(self.time_s / self.step_s))
        return 1e3 * self._physics_wall_s / steps

    def world_T_base(self, state: Optional[RobotState] = None) -> np.ndarray:
        if state is None:
            return self.physics.base_pose_matrix()
        return pose_matrix(state.position_m, state.orientation_xyzw)

    # ------------------------------------------------------------------ stepping
    def step(self) -> List[object]:
        """Advance one physics step; return the readings that are out, in order.

        Serial: the readings due at the new time. Pipelined: also the
        finished ones of earlier steps, and none after a pending one.
        Sensor faults (``faults``) have changed or dropped readings already.
        """
        readings = self._step()
        if readings and not self.faults.idle:
            return self._apply_faults(readings)
        return readings

    def _apply_faults(self, readings: List[object]) -> List[object]:
        out = []
        for r in readings:
            if isinstance(r, GpsReading):
                r = self.faults.gps(r)
            elif isinstance(r, CameraReading):
                r = self.faults.camera(r)
            elif isinstance(r, LidarReading):
                r = self.faults.lidar(r)
            if r is not None:
                out.append(r)
        return out

    def _step(self) -> List[object]:
        before = self.time_s
        t0 = time.perf_counter()
        self.physics.step()
        self._physics_wall_s += time.perf_counter() - t0
        self.arm_system.step(self.time_s, self.step_s, self.world_T_base)
        self._contacts.extend(self.physics.contacts_since_last_call())
        now = self.time_s
        readings: List[object] = []
        held = self._held
        if now + 1e-9 < self._next_due_s:
            if held:
                self._release_held(now, readings)
            return readings
        if held:
            # only what is finished: a job whose deadline is now is waited for after this step's
            # jobs are submitted, so that the worker goes on with them meanwhile
            self._release_held(now, readings, wait=False)
        state: Optional[RobotState] = None
        next_due = math.inf
        workers = self._workers
        for sched in self._schedules.values():
            if now + 1e-9 >= sched.next_s and sched.due(now) and self._render_due(sched.name, now):
                if state is None:
                    state = self.physics.robot_state()
                if workers is not None and sched.name in self._jobs:
                    # Due again at next_s (<= now + period): the step that reaches it waits for
                    # this job (after submitting the next one, which runs after it).
                    produce, args = self._jobs[sched.name](now, state)
                    previous = self._last_job.get(sched.name)
                    if previous is not None and previous.done():
                        previous = None
                    future = workers.submit(timed_job, previous, produce, *args)
                    self._last_job[sched.name] = future
                    held.append(HeldReading(now, before, sched.next_s, sched, future, None))
                    self._held_deadline_s = min(self._held_deadline_s, sched.next_s)
                else:
                    # pipelined: only this thread's CPU (the workers run meanwhile)
                    cpu_clock = time.process_time if workers is None else time.thread_time
                    t1, c1 = time.perf_counter(), cpu_clock()
                    reading = self._produce(sched.name, now, state)
                    sched.wall_s += time.perf_counter() - t1
                    sched.cpu_s += cpu_clock() - c1
                    sched.count += 1
                    if reading is not None:
                        if held:
                            held.append(HeldReading(now, before, math.inf, None, None, reading))
                        else:
                            readings.append(reading)
                            self._delivered_s = now
            if sched.next_s < next_due:
                next_due = sched.next_s
        self._next_due_s = next_due
        if held:
            self._release_held(now, readings)
        return readings

    def _render_due(self, name: str, now: float) -> bool:
        """False for a camera frame that its render_rate_hz skips (not the first of its slot)."""
        gate = self._render_gates.get(name)
        return gate is None or gate.take(now)

    def _release_held(self, now: float, out: List[object], wait: bool = True) -> None:
        """Append to ``out`` the held readings that are out at sim time ``now``, in order.

        First (``wait``) waits for every job whose deadline has come (and for
        what is before it), then takes the finished ones from the front.
        """
        held = self._held
        n_before = len(out)
        if wait and now + 1e-9 >= self._held_deadline_s:
            last = -1
            for i, slot in enumerate(held):
                if slot.future is not None and slot.deadline_s <= now + 1e-9:
                    last = i
            for _ in range(last + 1):
                out.append(self._finish(held.popleft()))
        while held and (held[0].future is None or held[0].future.done()):
            out.append(self._finish(held.popleft()))
        if len(out) > n_before:
            self._held_deadline_s = min((h.deadline_s for h in held if h.future is not None), default=math.inf)

    def _finish(self, slot: HeldReading) -> object:
        """The reading of a held slot (waits for its job); books the job's cost to its sensor."""
        if slot.future is None:
            reading = slot.reading
        else:
            if not slot.future.done():
                t0 = time.perf_counter()
                slot.future.result()
                self._sensor_wait_s += time.perf_counter() - t0
            reading, wall_s, cpu_s = slot.future.result()
            sched = slot.schedule
            sched.wall_s += wall_s
            sched.cpu_s += cpu_s
            sched.count += 1
        self._delivered_s = slot.stamp_s
        return reading

    def flush_readings(self) -> List[object]:
        """Wait for every pending sensor job; the readings not returned yet, in order (end of a run)."""
        out: List[object] = []
        while self._held:
            out.append(self._finish(self._held.popleft()))
        self._held_deadline_s = math.inf
        return out if self.faults.idle else self._apply_faults(out)

    def step_for(self, duration_s: float) -> List[object]:
        """Step for ``duration_s`` of sim time; the readings returned meanwhile, in order.

        Pipelined, the last ones may still be pending: ``flush_readings()`` returns them.
        """
        out: List[object] = []
        end = self.time_s + duration_s
        while self.time_s < end - 1e-9:
            out.extend(self.step())
        return out

    def _produce(self, name: str, now: float, state: RobotState):
        if name in self.cameras or name == "lidar":
            produce, args = self._jobs[name](now, state)
            return produce(*args)
        if name == "imu":
            m = self.imu.measure(now, state.orientation_xyzw, state.angular_velocity_body_rad_s,
                                 state.linear_acceleration_body_m_s2)
            if math.isfinite(m.angular_velocity_rad_s[2]):
                self.ekf.update_imu(float(m.angular_velocity_rad_s[2]), float(m.angular_velocity_covariance[8]),
                                    accel_body_m_s2=m.linear_acceleration_m_s2, orientation_xyzw=m.orientation_xyzw)
            return ImuReading(now, IMU_FRAME, self.imu_mount.in_imu_axes(m))
        if name == "gps":
            dt = now - self._last_gps_s
            self._last_gps_s = now
            noisy = self.gps_noise.apply(state.position_m, dt)
            x, y, z = noisy.tolist()
            lat, lon, alt = self.geodesy.world_to_geodetic(x, y, z)
            # The original's hector plugin reports the base_link position (its bodyName); so do we.
            return GpsReading(now, BASE_FRAME, lat, lon, alt, self._gps_variance_m2)
        if name == "odometry":
            dt = now - self._last_odom_s
            self._last_odom_s = now
            self.wheel_odometry.update(state.wheel_velocities_rad_s, dt)
            wheel = self.wheel_odometry.estimate()
            self.ekf.predict(dt)
            self.ekf.update_wheel_odometry(wheel.linear_x_m_s, wheel.angular_z_rad_s,
                                           (wheel.twist_covariance[0, 0], wheel.twist_covariance[5, 5]))
            return OdometryReading(now, wheel, self.ekf.output())
        if name == "joint_states":
            names = list(self._joint_names)
            positions = np.concatenate([state.wheel_angles_rad, self.arm.positions])
            velocities = np.concatenate([state.wheel_velocities_rad_s, self.arm.velocities])
            return JointStatesReading(now, names, positions, velocities)
        if name == "ground_truth":
            return GroundTruthReading(now, state)
        if name == "contacts":
            events, self._contacts = self._contacts, []
            return ContactsReading(now, events, self.physics.total_contact_events,
                                   sorted(self.physics.plants_touched))
        if name == "arm_contacts":
            return ArmContactsReading(now, self.arm_system.take_contact_events(), dict(self.arm_contacts.totals),
                                      sorted(self.arm_contacts.plants_touched))
        raise KeyError(name)

    # Cameras and LiDAR in two halves: what they need from the main thread, taken when they fall
    # due (the sensor pose from the physics state, switches), and the work on it, which touches
    # only that sensor's model (its scene is read-only), so a worker thread can run it.
    def _boll_visibility(self) -> BollVisibility:
        """The sensor scene's boll snapshot, brought up to date with ``bolls`` first."""
        scene = self.sensor_scene
        if scene.visibility.revision != self.bolls.revision:
            scene.set_hidden_bolls(self.bolls.off_plant_mask(), self.bolls.revision)
        return scene.visibility

    def _camera_job(self, name: str, now: float, state: RobotState):
        world_T_optical = self.world_T_base(state) @ self.base_T_sensor[name]
        return self._camera, (name, now, world_T_optical, self._camera_cloud_wanted[name], self._boll_visibility())

    def _lidar_job(self, now: float, state: RobotState):
        world_T_lidar = self.world_T_base(state) @ self.base_T_sensor[LIDAR_FRAME]
        return self._lidar, (now, world_T_lidar, self._boll_visibility())

    def _camera(self, name: str, now: float, world_T_optical: np.ndarray, cloud_wanted: bool,
                visibility: BollVisibility) -> CameraReading:
        camera = self.cameras[name]
        frame = camera.render(world_T_optical, visibility)
        reading = CameraReading(now, name, optical_frame(name), frame, camera.intrinsics())
        if cloud_wanted:
            packed, reading.cloud_rgb = camera.point_cloud_xyzrgb(frame)
            reading.cloud_xyzrgb = packed
            reading.cloud_xyz = packed[:, :3]
        return reading

    def _lidar(self, now: float, world_T_lidar: np.ndarray, visibility: BollVisibility) -> LidarReading:
        scan = self.lidar.scan(world_T_lidar, visibility)
        kept = original_passthrough(scan.points, self.config.passthrough)
        ranges, ranges_360 = cloud_to_laserscans(scan.points, (self.config.laserscan, self.config.laserscan_360))
        return LidarReading(now, LIDAR_FRAME, scan, kept, ranges, self.config.laserscan,
                            ranges_360, self.config.laserscan_360)

    def close(self) -> None:
        """Stop the sensor workers (pending readings are dropped) and free the sensor scene."""
        if self._workers is not None:
            for slot in self._held:
                if slot.future is not None:
                    slot.future.cancel()
            self._workers.shutdown(wait=True)
            self._workers = None
            if self._saved_switch_interval_s is not None:
                sys.setswitchinterval(self._saved_switch_interval_s)
                self._saved_switch_interval_s = None
            self._held.clear()
            self._held_deadline_s = math.inf
        if self.sensor_scene is not None:
            self.sensor_scene.close()
            self.sensor_scene = None
