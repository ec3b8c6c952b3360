"""Rigid-body dynamics of the Husky in the cotton field, with ODE.

The original CottonSim ran Gazebo 11 on the Open Dynamics Engine (ODE).
This module drives the same engine (Debian's python3-pyode, ``import ode``)
directly: a flat ground plane, the farm's plants as static collision
geometry, and the Husky as five bodies (chassis + four wheels on hinge
joints whose velocity motors follow ``DiffDriveController``).

Why the wheel-soil contact is built as it is (isotropic Coulomb friction
with the first friction direction along each wheel's sliding velocity, one
merged contact joint per wheel, soft ERP / CFM from a spring-damper), what
it gives (the closed-form spin rate of a skid-steer robot, checked), and
how collisions are filtered: docs/physics.md.

The bodies and geoms are built by ``ode_bodies``; the library's constants
(pyode's own predate ODE 0.16) come from ``ode_library``.
"""
from __future__ import annotations

import ctypes
import math
from collections import deque
from typing import Deque, Dict, List, Optional, Sequence, Set, Tuple

import numpy as np

from ..farm.model import Plant, Pose2D, Primitive
from .diff_drive import DiffDriveController
from .husky_params import DriveLimits, HuskyParams
from .ode_bodies import build_husky, finite_tuple, plant_primitives_in_world, static_geom
from .ode_library import (CAT_GROUND, CAT_ROBOT, MODE_APPROX1, MODE_FDIR1, MODE_MU2, MODE_SLIP1, MODE_SLIP2,
                          MODE_SOFT_CFM, MODE_SOFT_ERP, PARAM_VEL, ode)
from .physics_config import ContactEvent, PhysicsConfig, RobotState

_TWO_PI = 2.0 * math.pi


class OdeWorld:
    """The ODE world: ground, static plants, one Husky.

    Typical use::

        world = OdeWorld(PhysicsConfig(), HuskyParams(), DriveLimits())
        world.add_plants(farm.plants)
        world.spawn_robot(farm.spawn)
        world.set_command(0.5, 0.0, world.sim_time_s)   # from /cmd_vel
        for _ in range(n): world.step()
        state = world.robot_state()
        events = world.contacts_since_last_call()
    """

    def __init__(self, config: PhysicsConfig = PhysicsConfig(), husky: HuskyParams = HuskyParams(),
                 limits: DriveLimits = DriveLimits()):
        self.config = config
        self.husky = husky
        self.limits = limits
        # ODE's solver draws from one process-wide random generator (quickStep
        # reorders constraints randomly). Re-seeding it before every step from
        # (seed, step count) makes each world's run independent of any other
        # world stepped in the same process, so runs replay bit for bit.
        self._rand_set_seed = ctypes.CDLL("libode.so.8").dRandSetSeed
        self._rand_set_seed.argtypes = [ctypes.c_ulong]
        self._rand_set_seed.restype = None
        self._rand_set_seed(config.seed)
        self._seed_base = config.seed * 1_000_003
        self._world = ode.World()
        self._world.setGravity((0.0, 0.0, config.gravity_m_s2))
        self._world.setQuickStepNumIterations(config.solver_iterations)
        self._world.setContactSurfaceLayer(config.contact_surface_layer_m)
        self._world.setContactMaxCorrectingVel(config.contact_max_correcting_vel_m_s)
        self._world.setAutoDisableFlag(False)
        h = config.step_s
        kp, kd = config.contact_stiffness_n_m, config.contact_damping_n_s_m
        self._soft_erp = h * kp / (h * kp + kd)
        self._soft_cfm = 1.0 / (h * kp + kd)
        # ODE's HashSpace tests a foreign geom against *every* geom it holds
        # (dSpaceCollide2 is brute force there); a quadtree prunes by cell:
        # 0.005 ms instead of 0.06 ms per step for the 720-geom default farm.
        # The quadtree holds the plants only: the ground plane is collided
        # with each robot geom directly (``_collide_ground``), so the Python
        # near-callback of collide2 runs only while the robot is near a plant.
        cx, cy = config.broadphase_centre_m
        ext = config.broadphase_extent_m
        self._static_space = ode.QuadTreeSpace((cx, cy, 0.0), (ext, ext, ext), config.broadphase_depth)
        self._robot_space = ode.SimpleSpace()
        self._contact_group = ode.JointGroup()
        self._ground = ode.GeomPlane(None, (0.0, 0.0, 1.0), 0.0)
        self._ground.setCategoryBits(CAT_GROUND)
        self._ground.setCollideBits(CAT_ROBOT)
        # id(geom) -> ("plant", plant_id) or ("robot", part name, body, is_wheel)
        self._geom_info: Dict[int, Tuple] = {id(self._ground): ("ground", None)}
        self._static_geoms: List[object] = [self._ground]   # keep Python refs alive
        self._plant_ids: Set[int] = set()
        # Contact surfaces, fixed per pair kind: (mode, mu, mu2, slip, soft_cfm).
        soft = MODE_SOFT_ERP | MODE_SOFT_CFM
        self._surface_wheel_ground = (MODE_APPROX1 | MODE_SLIP1 | MODE_SLIP2 | MODE_FDIR1 | soft,
                                      config.wheel_mu, config.wheel_mu, config.wheel_slip, self._soft_cfm)
        self._surface_chassis_ground = (MODE_APPROX1 | soft, config.chassis_mu, config.chassis_mu, 0.0,
                                        self._soft_cfm)
        self._surface_plant = (MODE_APPROX1 | MODE_MU2 | soft, config.plant_mu1, config.plant_mu2, 0.0,
                               self._soft_cfm)
        # (geom, body, is_wheel) of each robot geom, for the ground pass
        self._ground_pairs: List[Tuple[object, object, bool]] = []
        self._wheel_templates: Dict[int, object] = {}     # n merged points -> ode.Contact
        self._wheel_radius_m = husky.wheel_radius_m
        self._wheel_half_width_m = 0.5 * husky.wheel_width_m
        self._touching_now: Set[Tuple[int, str]] = set()

        self._controller = DiffDriveController(husky, limits)
        self._control_period_s = 1.0 / limits.control_rate_hz
        self._next_control_s = 0.0
        self._wheel_targets: Tuple[float, float] = (0.0, 0.0)   # last (left, right) sent to the motors [rad/s]
        self._step_count = 0
        self._chassis = None
        self._wheels: List[object] = []
        self._hinges: List[object] = []
        self._robot_geoms: List[object] = []
        # plain-float bookkeeping (numpy's per-call cost dominates for 3- and 4-vectors)
        self._wheel_angle: List[float] = [0.0] * 4
        self._wheel_raw_prev: List[float] = [0.0] * 4
        self._base_offset: Tuple[float, float, float] = (0.0, 0.0, 0.0)   # base_link origin in the chassis body
        self._vel_history: Deque[Tuple[float, Tuple[float, float, float]]] = deque()

        self._last_touch_s: Dict[Tuple[int, str], float] = {}
        self._pending_events: List[ContactEvent] = []
        self.total_contact_events = 0
        self.plants_touched: Set[int] = set()

    # ------------------------------------------------------------------ time
    @property
    def sim_time_s(self) -> float:
        """Simulated time [s]; step count x step_s (no accumulated rounding)."""
        return self._step_count * self.config.step_s

    @property
    def controller(self) -> DiffDriveController:
        return self._controller

    # --------------------------------------------------------------- plants
    def add_plants(self, plants: Sequence[Plant]) -> int:
        """Add each plant's model.collision primitives, placed at its pose.

        Returns the number of geoms added. Plants are static (no body).
        """
        return sum(self.add_static_obstacles(plant.plant_id, plant_primitives_in_world(plant)) for plant in plants)

    def add_static_obstacles(self, plant_id: int, primitives_in_world: Sequence[Primitive]) -> int:
        """Add static collision primitives (world frame) that belong to plant_id."""
        added = [static_geom(self._static_space, plant_id, prim) for prim in primitives_in_world]
        for geom in added:
            self._geom_info[id(geom)] = ("plant", int(plant_id))
        self._static_geoms.extend(added)
        self._plant_ids.add(int(plant_id))
        return len(added)

    @property
    def static_geom_count(self) -> int:
        return len(self._static_geoms) - 1

    # ---------------------------------------------------------------- robot
    def spawn_robot(self, pose: Pose2D) -> None:
        """Place the Husky at rest on the ground at pose (base_link x, y, yaw).

        Spawning again removes the previous robot and resets the controller.
        """
        x, y, yaw = finite_tuple((pose.x_m, pose.y_m, pose.yaw_rad), 3, "spawn pose (x_m, y_m, yaw_rad)")
        if self._chassis is not None:
            self._remove_robot()
        husky = build_husky(self._world, self._robot_space, self.husky, x, y, yaw, self.config.wheel_max_torque_n_m)
        for g, part, body in husky.geoms:
            self._geom_info[id(g)] = ("robot", part, body, part != "chassis")
        self._chassis = husky.chassis
        self._wheels = husky.wheels
        self._hinges = husky.hinges
        self._robot_geoms = [g for g, _, _ in husky.geoms]
        self._ground_pairs = [(g, body, part != "chassis") for g, part, body in husky.geoms]
        com_offset = husky.com_offset_m
        self._base_offset = (-float(com_offset[0]), -float(com_offset[1]), -float(com_offset[2]))
        self._wheel_angle = [0.0] * 4
        self._wheel_raw_prev = [h.getAngle() for h in self._hinges]
        self._vel_history.clear()
        self._controller.reset()
        self._wheel_targets = (0.0, 0.0)
        self._next_control_s = self.sim_time_s

    def _remove_robot(self) -> None:
        for g in self._robot_geoms:
            self._geom_info.pop(id(g), None)
            self._robot_space.remove(g)
        for h in self._hinges:
            h.attach(None, None)
        self._robot_geoms, self._hinges, self._wheels, self._chassis = [], [], [], None
        self._ground_pairs = []

    def _require_robot(self) -> None:
        if self._chassis is None:
            raise RuntimeError("no robot in the world: call spawn_robot(pose) first")

    # -------------------------------------------------------------- command
    def set_command(self, linear_x: float, angular_z: float, stamp_s: Optional[float] = None) -> Optional[str]:
        """Twist command [m/s, rad/s] stamped in sim time [s] (default: now).

        Returns None if accepted, else the reason it was ignored (NaN/inf).
        """
        return self._controller.set_command(linear_x, angular_z, self.sim_time_s if stamp_s is None else stamp_s)

    # ----------------------------------------------------------------- step
    def step(self) -> None:
        """Advance the world by config.step_s."""
        self._require_robot()
        now = self._step_count * self.config.step_s
        if now >= self._next_control_s - 1e-9:
            targets = self._controller.update(now)
            left, right = targets.left_rad_s, targets.right_rad_s
            if (left, right) != self._wheel_targets:     # the motors keep their last target
                self._wheel_targets = (left, right)
                for i, hinge in enumerate(self._hinges):
                    hinge.setParam(PARAM_VEL, left if i % 2 == 0 else right)
            self._next_control_s += self._control_period_s
        touching = self._touching_now
        if touching:
            touching.clear()
        self._rand_set_seed((self._seed_base + self._step_count) & 0xFFFFFFFF)
        self._collide_ground()
        ode.collide2(self._robot_space, self._static_space, None, self._near_callback)
        self._world.quickStep(self.config.step_s)
        self._contact_group.empty()
        self._step_count += 1
        t = self._step_count * self.config.step_s
        for key in touching:
            self._last_touch_s[key] = t
        # unwrapped wheel angles: add each hinge's change, wrapped to (-pi, pi]
        prev, acc = self._wheel_raw_prev, self._wheel_angle
        raw = [h.getAngle() for h in self._hinges]
        for i in range(4):
            acc[i] += (raw[i] - prev[i] + math.pi) % _TWO_PI - math.pi
        self._wheel_raw_prev = raw
        history = self._vel_history
        history.append((t, self._chassis.getRelPointVel(self._base_offset)))
        window = self.config.accel_window_s - 1e-12
        while len(history) > 2 and t - history[1][0] >= window:
            history.popleft()

    def step_for(self, duration_s: float) -> None:
        """Step until duration_s [s] of sim time have passed."""
        if not math.isfinite(duration_s) or duration_s < 0:
            raise ValueError(f"duration_s must be finite and >= 0, got {duration_s!r}")
        for _ in range(int(round(duration_s / self.config.step_s))):
            self.step()

    # ------------------------------------------------------------- contacts
    # These run several times per step, so they use plain floats and the
    # surfaces prepared in __init__ (numpy's per-call overhead on 3-vectors
    # would cost more than ODE's collision test itself).
    def _collide_ground(self) -> None:
        """Contacts of every robot geom with the ground plane (z = 0)."""
        ground = self._ground
        max_n = self.config.max_contacts_per_pair
        merge = self.config.merge_wheel_contacts
        for geom, body, is_wheel in self._ground_pairs:
            if is_wheel and merge and self._merged_wheel_contact(geom, body):
                continue
            contacts = ode.collide(geom, ground)
            if not contacts:
                continue
            if not is_wheel:
                self._add_contacts(body, contacts[:max_n], self._surface_chassis_ground)
            elif merge:
                self._add_merged_contacts(geom, body, contacts)
            else:
                for c in contacts[:max_n]:
                    pos, normal, depth, _g1, _g2 = c.getContactGeomParams()
                    self._add_wheel_contact(geom, body, 1, pos, normal, depth, None)

    def _merged_wheel_contact(self, geom, body) -> bool:
        """Add the wheel's merged ground contact, computed here; False if ODE must do it.

        ODE's cylinder-plane test reports, for a wheel whose axle is not
        near vertical, the lowest point of each rim circle that lies below
        the plane (depth = -z). With the wheel centre c, unit axle a and
        u = (z - a_z a) / |z - a_z a| (the in-wheel direction closest to
        up), those points are c +/- (w/2) a - r u. Computing them here costs
        a fraction of ode.collide plus reading its contacts back; the mean
        of the touching ones becomes one joint. A wheel lying flat
        (|a_z| ~ 1) is left to ode.collide.
        """
        _r00, ax, _r02, _r10, ay, _r12, _r20, az, _r22 = body.getRotation()   # axle = body y = column 1
        s2 = 1.0 - az * az
        if s2 < 1e-4:
            return False
        cx, cy, cz = body.getPosition()
        root = math.sqrt(s2)
        radius, half_width = self._wheel_radius_m, self._wheel_half_width_m
        # -r u = (k a_x, k a_y, -r root), with k = r a_z / root
        k = radius * az / root
        bottom_z = cz - radius * root
        depth_plus = -(bottom_z + half_width * az)      # rim at c + (w/2) a
        depth_minus = -(bottom_z - half_width * az)     # rim at c - (w/2) a
        if depth_plus > 0.0 and depth_minus > 0.0:
            n, depth, along = 2, 0.5 * (depth_plus + depth_minus), 0.0
        elif depth_plus > 0.0:
            n, depth, along = 1, depth_plus, half_width
        elif depth_minus > 0.0:
            n, depth, along = 1, depth_minus, -half_width
        else:
            return True                                 # in the air: no contact
        pos = (cx + (along + k) * ax, cy + (along + k) * ay, bottom_z + along * az)
        self._add_wheel_contact(geom, body, n, pos, (0.0, 0.0, 1.0), depth, (ax, ay, az))
        return True

    def _add_merged_contacts(self, geom, body, contacts) -> None:
        """One joint for a wheel's ODE contacts: mean point and depth, summed stiffness."""
        n = len(contacts)
        px = py = pz = nx = ny = nz = depth = 0.0
        for c in contacts:
            (x, y, z), (a, b, d), dep, _g1, _g2 = c.getContactGeomParams()
            px += x
            py += y
            pz += z
            nx += a
            ny += b
            nz += d
            depth += dep
        norm = math.sqrt(nx * nx + ny * ny + nz * nz)
        self._add_wheel_contact(geom, body, n, (px / n, py / n, pz / n), (nx / norm, ny / norm, nz / norm),
                                depth / n, None)

    def _wheel_contact_template(self, n: int):
        """Wheel-ground contact surface standing for n parallel points: stiffness x n, slip / n.

        ODE copies the contact into each joint, so one template per n
        serves every wheel; only the point, depth and friction direction
        change per step.
        """
        contact = self._wheel_templates.get(n)
        if contact is None:
            mode, mu, _mu2, slip, cfm = self._surface_wheel_ground
            contact = ode.Contact()
            contact.setMode(mode)
            contact.setMu(mu)
            contact.setSlip1(slip / n)
            contact.setSlip2(slip / n)
            contact.setSoftERP(self._soft_erp)
            contact.setSoftCFM(cfm / n)
            self._wheel_templates[n] = contact
        return contact

    def _add_wheel_contact(self, geom, body, n: int, pos, normal, depth: float, axle) -> None:
        """Joint for a wheel-ground contact of n merged points at pos (axle: unit vector or None)."""
        contact = self._wheel_templates.get(n) or self._wheel_contact_template(n)
        contact.setContactGeomParams(pos, normal, depth, geom, self._ground)
        contact.setFDir1(self._sliding_direction(body, pos, normal, axle))
        ode.ContactJoint(self._world, self._contact_group, contact).attach(body, None)

    def _add_contacts(self, body, contacts, surface) -> None:
        mode, mu, mu2, slip, cfm = surface
        for c in contacts:
            c.setMode(mode)
            c.setMu(mu)
            c.setMu2(mu2)
            if slip > 0.0:
                c.setSlip1(slip)
                c.setSlip2(slip)
            c.setSoftERP(self._soft_erp)
            c.setSoftCFM(cfm)
            ode.ContactJoint(self._world, self._contact_group, c).attach(body, None)

    def _near_callback(self, _arg, g1, g2) -> None:
        """collide2 callback: a robot geom's box overlaps a plant geom's box."""
        info1 = self._geom_info.get(id(g1))
        info2 = self._geom_info.get(id(g2))
        if info1 is None or info2 is None:
            return
        if info1[0] != "robot":
            g1, g2, info1, info2 = g2, g1, info2, info1
        if info1[0] != "robot" or info2[0] != "plant":
            return
        contacts = ode.collide(g1, g2)
        if not contacts:
            return
        self._register_touch(int(info2[1]), info1[1], contacts[0])
        self._add_contacts(info1[2], contacts[:self.config.max_contacts_per_pair], self._surface_plant)

    @staticmethod
    def _sliding_direction(body, pos, normal, axle=None) -> Tuple[float, float, float]:
        """Unit tangent along which the wheel surface slides over the ground at pos.

        ODE bounds friction per direction (a pyramid); aligning the first
        direction with the sliding velocity makes the saturated friction
        force oppose the slip as isotropic Coulomb friction would. Without
        sliding, the wheel's rolling direction (axle x normal) is used.
        """
        nx, ny, nz = normal
        vx, vy, vz = body.getPointVel(pos)
        vn = vx * nx + vy * ny + vz * nz
        tx, ty, tz = vx - vn * nx, vy - vn * ny, vz - vn * nz
        speed = math.sqrt(tx * tx + ty * ty + tz * tz)
        if speed > 1e-4:
            return (tx / speed, ty / speed, tz / speed)
        ax, ay, az = axle if axle is not None else body.vectorToWorld((0.0, 1.0, 0.0))
        fx, fy, fz = ay * nz - az * ny, az * nx - ax * nz, ax * ny - ay * nx   # axle x normal
        norm = math.sqrt(fx * fx + fy * fy + fz * fz)
        return (fx / norm, fy / norm, fz / norm) if norm > 1e-9 else (1.0, 0.0, 0.0)

    def _register_touch(self, plant_id: int, part: str, contact) -> None:
        key = (plant_id, part)
        if key in self._touching_now:          # already seen this step (another geom / point)
            return
        self._touching_now.add(key)
        now = self.sim_time_s
        last = self._last_touch_s.get(key)
        if last is not None and now - last <= self.config.contact_rearm_s:
            return                             # still the same touch
        pos, _normal, depth, _g1, _g2 = contact.getContactGeomParams()
        self._pending_events.append(ContactEvent(now, plant_id, part, tuple(float(v) for v in pos), float(depth)))
        self.total_contact_events += 1
        self.plants_touched.add(plant_id)

    # ---------------------------------------------------------------- output
    def contacts_since_last_call(self) -> List[ContactEvent]:
        """Touch events (a robot part started touching a plant) since the last call."""
        out, self._pending_events = self._pending_events, []
        return out

    def base_pose_matrix(self) -> np.ndarray:
        """4x4 pose of base_link in the world now (robot_state's position and orientation, cheaper)."""
        self._require_robot()
        ch = self._chassis
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = ch.getRotation()
        ox, oy, oz = self._base_offset
        cx, cy, cz = ch.getPosition()
        return np.array(((r00, r01, r02, cx + r00 * ox + r01 * oy + r02 * oz),
                         (r10, r11, r12, cy + r10 * ox + r11 * oy + r12 * oz),
                         (r20, r21, r22, cz + r20 * ox + r21 * oy + r22 * oz),
                         (0.0, 0.0, 0.0, 1.0)))

    def robot_state(self) -> RobotState:
        """Ground-truth state of the Husky now."""
        self._require_robot()
        ch = self._chassis
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = ch.getRotation()    # row-major, body -> world
        ox, oy, oz = self._base_offset
        cx, cy, cz = ch.getPosition()
        base_pos = (cx + r00 * ox + r01 * oy + r02 * oz,
                    cy + r10 * ox + r11 * oy + r12 * oz,
                    cz + r20 * ox + r21 * oy + r22 * oz)
        qw, qx, qy, qz = ch.getQuaternion()
        v_world = ch.getRelPointVel(self._base_offset)
        w_world = ch.getAngularVel()
        history = self._vel_history
        if len(history) >= 2:
            (t0, v0), (t1, v1) = history[0], history[-1]
            inv_dt = 1.0 / (t1 - t0)
            a_world = ((v1[0] - v0[0]) * inv_dt, (v1[1] - v0[1]) * inv_dt, (v1[2] - v0[2]) * inv_dt)
        else:
            a_world = (0.0, 0.0, 0.0)
        specific_force = (a_world[0], a_world[1], a_world[2] - self.config.gravity_m_s2)

        def to_body(v):   # R^T v
            return np.array((r00 * v[0] + r10 * v[1] + r20 * v[2],
                             r01 * v[0] + r11 * v[1] + r21 * v[2],
                             r02 * v[0] + r12 * v[1] + r22 * v[2]))

        return RobotState(
            stamp_s=self.sim_time_s,
            position_m=np.array(base_pos),
            orientation_xyzw=np.array((qx, qy, qz, qw)),
            linear_velocity_world_m_s=np.array(v_world),
            linear_velocity_body_m_s=to_body(v_world),
            angular_velocity_world_rad_s=np.array(w_world),
            angular_velocity_body_rad_s=to_body(w_world),
            linear_acceleration_body_m_s2=to_body(specific_force),
            wheel_angles_rad=np.array(self._wheel_angle),
            wheel_velocities_rad_s=np.array([h.getAngleRate() for h in self._hinges]),
        )
