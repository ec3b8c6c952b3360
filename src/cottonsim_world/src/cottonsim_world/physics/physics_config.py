"""The ODE world's parameters and what it reports: its config, the robot's state, a plant touch.

Kept apart from ``ode_world`` so that readers of the simulator's state
(the bridge, the sensors, the evaluation) need not import ODE.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from cottonsim_common.validation import require_fields


@dataclass(frozen=True)
class PhysicsConfig:
    """Parameters of the ODE world.

    step_s: physics step [s]. Gazebo's world used 0.001 s. Measured with
        quickStep, 50 iterations and merged wheel contacts (3 s spin at
        1 rad/s; 10 s arc at 0.5 m/s, 0.15 rad/s; 8 s slalom at 1 m/s,
        +/-1.5 rad/s with reversals; compared with 0.001 s):
        0.002 s: spin drift 0.00 mm, arc end 0.2 mm off, slalom end 1.7 cm off;
        0.004 s: 0.02 mm, 0.1 mm, 4.0 cm;
        0.005 s: 0.04 mm, 1.0 mm, 4.7 cm, rest z jitter 8e-7 m.
        (With one joint per rim point, 0.005 s drifted 13 mm in the spin.)
        0.005 s is the default: every rate of the simulator (50, 40, 100
        and 10 Hz) is a whole number of steps, and a simulated second costs
        ~40 % of the instructions of 0.002 s (docs/benchmarks.md).
    gravity_m_s2: z component of gravity [m/s^2].
    solver_iterations: quickStep iterations per step.
    wheel_mu: Coulomb friction of wheel on soil, along (mu1) and across
        (mu2) the wheel; 1.0 as in husky_description's wheel.urdf.xacro.
    wheel_slip: ODE force-dependent slip along and across the wheel
        [(m/s)/N]: the wheel surface creeps at slip x force before it
        slides; 0.001 gives ~0.04 m/s creep at full (3 m/s^2) acceleration
        and a first-order lag of ~15 ms. The same both ways (isotropic).
    chassis_mu: friction of the chassis on ground or plants.
    plant_mu1 / plant_mu2: friction of a plant against the robot (the
        original's plant collision parts: mu1 100, mu2 50).
    contact_stiffness_n_m / contact_damping_n_s_m: normal spring-damper of
        every contact, converted to soft ERP/CFM for step_s.
    contact_surface_layer_m: ODE contact surface layer (allowed resting
        penetration) [m]; contact_max_correcting_vel_m_s: cap on the speed at
        which penetration is corrected [m/s].
    max_contacts_per_pair: contact points per colliding robot-plant or
        chassis-ground geom pair.
    merge_wheel_contacts: give each wheel touching the ground one contact
        joint instead of ODE's two rim points: at their mean position and
        depth, with the pair's summed stiffness and damping (ERP unchanged,
        CFM / n) and the slip of the two in parallel (wheel_slip / n), so
        the wheel feels the same spring, damper and creep. It removes a
        third of the solver's constraint rows (see docs/benchmarks.md);
        False keeps one joint per rim point (as before).
    wheel_max_torque_n_m: motor torque limit per wheel (ParamFMax) [N m].
    accel_window_s: window of the finite difference that gives the body
        acceleration for the IMU [s].
    contact_rearm_s: a (plant, part) touch is reported again only after the
        pair was apart for this long [s], so contact flicker is one event.
    broadphase_centre_m / broadphase_extent_m / broadphase_depth: the
        quadtree (ODE QuadTreeSpace) that holds ground and plants: centre
        (x, y) [m], extent [m] and depth; geoms outside still collide, only
        slower.
    seed: seeds ODE's random generator (quickStep reorders constraints
        randomly), so runs with the same inputs are bit-identical.
    """

    step_s: float = 0.005
    gravity_m_s2: float = -9.8
    solver_iterations: int = 50
    wheel_mu: float = 1.0
    wheel_slip: float = 0.001
    chassis_mu: float = 0.5
    plant_mu1: float = 100.0
    plant_mu2: float = 50.0
    contact_stiffness_n_m: float = 1.0e6
    contact_damping_n_s_m: float = 5.0e3
    contact_surface_layer_m: float = 0.0005
    contact_max_correcting_vel_m_s: float = 1.0
    max_contacts_per_pair: int = 4
    merge_wheel_contacts: bool = True
    wheel_max_torque_n_m: float = 40.0
    accel_window_s: float = 0.02
    contact_rearm_s: float = 0.1
    broadphase_centre_m: Tuple[float, float] = (0.0, 0.0)
    broadphase_extent_m: float = 256.0
    broadphase_depth: int = 8
    seed: int = 0

    def __post_init__(self) -> None:
        require_fields(self, "PhysicsConfig.",
                       positive=("step_s", "wheel_mu", "chassis_mu", "plant_mu1", "plant_mu2",
                                 "contact_stiffness_n_m", "contact_max_correcting_vel_m_s", "wheel_max_torque_n_m",
                                 "accel_window_s", "broadphase_extent_m"),
                       non_negative=("wheel_slip", "contact_damping_n_s_m", "contact_surface_layer_m",
                                     "contact_rearm_s"),
                       flags=("merge_wheel_contacts",))
        if self.step_s > 0.02:
            raise ValueError(f"PhysicsConfig.step_s must be <= 0.02 s for a stable wheel contact, got {self.step_s}")
        if not math.isfinite(self.gravity_m_s2) or self.gravity_m_s2 >= 0:
            raise ValueError(f"PhysicsConfig.gravity_m_s2 must be negative (z up), got {self.gravity_m_s2!r}")
        if not isinstance(self.solver_iterations, int) or self.solver_iterations < 1:
            raise ValueError(f"PhysicsConfig.solver_iterations must be an int >= 1, got {self.solver_iterations!r}")
        if not isinstance(self.max_contacts_per_pair, int) or not 1 <= self.max_contacts_per_pair <= 64:
            raise ValueError(f"PhysicsConfig.max_contacts_per_pair must be an int in 1..64, got {self.max_contacts_per_pair!r}")
        if len(self.broadphase_centre_m) != 2 or not all(math.isfinite(v) for v in self.broadphase_centre_m):
            raise ValueError(f"PhysicsConfig.broadphase_centre_m must be 2 finite numbers, got {self.broadphase_centre_m!r}")
        if not isinstance(self.broadphase_depth, int) or not 1 <= self.broadphase_depth <= 12:
            raise ValueError(f"PhysicsConfig.broadphase_depth must be an int in 1..12, got {self.broadphase_depth!r}")
        if not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"PhysicsConfig.seed must be an int >= 0, got {self.seed!r}")


@dataclass(frozen=True)
class RobotState:
    """True state of the Husky at ``stamp_s`` (world frame = ground truth).

    position_m: base_link origin (3,); orientation_xyzw: base_link attitude
    quaternion (x, y, z, w); *_world / *_body: the same vector in world and
    in base_link axes. linear_velocity_*: of the base_link origin [m/s];
    angular_velocity_* [rad/s]; linear_acceleration_body_m_s2: specific
    force at base_link as an accelerometer measures it (+9.8 on z at rest).
    wheel_angles_rad / wheel_velocities_rad_s: order FL, FR, RL, RR;
    angles are unwrapped (they keep counting).
    """

    stamp_s: float
    position_m: np.ndarray
    orientation_xyzw: np.ndarray
    linear_velocity_world_m_s: np.ndarray
    linear_velocity_body_m_s: np.ndarray
    angular_velocity_world_rad_s: np.ndarray
    angular_velocity_body_rad_s: np.ndarray
    linear_acceleration_body_m_s2: np.ndarray
    wheel_angles_rad: np.ndarray
    wheel_velocities_rad_s: np.ndarray

    @property
    def yaw_rad(self) -> float:
        x, y, z, w = self.orientation_xyzw
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


@dataclass(frozen=True)
class ContactEvent:
    """A robot part started touching a plant.

    point_m: world contact point (3,); depth_m: penetration at the first
    step of the touch [m].
    """

    stamp_s: float
    plant_id: int
    part: str
    point_m: Tuple[float, float, float]
    depth_m: float


# -- small quaternion helpers; ODE uses (w, x, y, z), the project (x, y, z, w)
