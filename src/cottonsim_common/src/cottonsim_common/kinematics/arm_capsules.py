"""The UR5e as nine capsules on its DH frames: what the arm occupies at given joints.

The planner's collision checks (cottonsim_manipulation.planning.collision)
and the simulator's arm-plant contact counter (cottonsim_world.robot.arm_contacts)
both take the arm's shape from here: base column, shoulder drum, upper-arm
tube, elbow drum, forearm tube, the three wrists and the vacuum nozzle on
the flange (ARM_LINKS). The radii are those of the UR5e's housings and tubes
as the robot description draws them (make_urdf.py). Frames: the arm's base
frame (the UR 'base', DH frame 0; ur5e_base in the URDF), metres.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from cottonsim_common.kinematics.ur5e import Ur5eKinematics, link_frames

ARM_LINKS: Tuple[str, ...] = (
    "base", "shoulder", "upper_arm", "elbow", "forearm", "wrist_1", "wrist_2", "wrist_3", "nozzle",
)


@dataclass(frozen=True)
class ArmCollisionConfig:
    """The UR5e's capsules and the margins of the checks (lengths in metres).

    base_radius_m: the base column, plate to shoulder (UR5e base: 149 mm across).
    shoulder_radius_m, elbow_radius_m: the shoulder and elbow drums.
    upper_arm_radius_m, forearm_radius_m: the tubes.
    wrist_radius_m: the three wrist housings and the flange.
    shoulder_offset_m: the upper-arm tube's offset along the shoulder-lift axis
        from the DH plane (UR5e: 0.138); forearm_offset_m: the forearm tube's.
    nozzle_length_m, nozzle_radius_m: the vacuum nozzle on the flange (its tip
        is nozzle_length_m along tool0's z); nozzle_tip_allowance_m: its last
        part, left out of the checks (it reaches into the boll).
    padding_m: added to every arm radius against plants and the body.
    self_padding_m: added to every arm radius in the self-collision check.
    """

    base_radius_m: float = 0.0745
    shoulder_radius_m: float = 0.060
    upper_arm_radius_m: float = 0.045
    elbow_radius_m: float = 0.050
    forearm_radius_m: float = 0.038
    wrist_radius_m: float = 0.045
    shoulder_offset_m: float = 0.138
    forearm_offset_m: float = 0.010
    nozzle_length_m: float = 0.15
    nozzle_radius_m: float = 0.02
    nozzle_tip_allowance_m: float = 0.03
    padding_m: float = 0.01
    self_padding_m: float = 0.0

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"ArmCollisionConfig.{name} must be a finite number, got {value!r}")
            if value < 0.0 or value > 1.0:
                raise ValueError(f"ArmCollisionConfig.{name} = {value} m must be in [0, 1]")
        if self.nozzle_tip_allowance_m > self.nozzle_length_m:
            raise ValueError("ArmCollisionConfig.nozzle_tip_allowance_m must not exceed nozzle_length_m")

    @property
    def radii_m(self) -> np.ndarray:
        """Radius of each capsule of ARM_LINKS, without padding [m]."""
        w = self.wrist_radius_m
        return np.array([self.base_radius_m, self.shoulder_radius_m, self.upper_arm_radius_m, self.elbow_radius_m,
                         self.forearm_radius_m, w, w, w, self.nozzle_radius_m])


def arm_capsule_segments(q_rad: np.ndarray, config: Optional[ArmCollisionConfig] = None,
                         kinematics: Optional[Ur5eKinematics] = None) -> Tuple[np.ndarray, np.ndarray]:
    """Segment ends (K, 9, 3), (K, 9, 3) of ARM_LINKS in the arm's base frame for joints (K, 6) or (6,) [rad]."""
    q = np.atleast_2d(np.asarray(q_rad, dtype=float))
    c = config or ArmCollisionConfig()
    f = link_frames(q, kinematics)
    o, z = f[:, :, :3, 3], f[:, :, :3, 2]
    sh, fo = c.shoulder_offset_m, c.forearm_offset_m
    nozzle_end = c.nozzle_length_m - c.nozzle_tip_allowance_m
    start = np.stack([o[:, 0], o[:, 1], o[:, 1] + sh * z[:, 1], o[:, 2] + sh * z[:, 2], o[:, 2] + fo * z[:, 2],
                      o[:, 3] + fo * z[:, 3], o[:, 4], o[:, 5], o[:, 6]], axis=1)
    end = np.stack([o[:, 1], o[:, 1] + sh * z[:, 1], o[:, 2] + sh * z[:, 2], o[:, 2] + fo * z[:, 2],
                    o[:, 3] + fo * z[:, 3], o[:, 4], o[:, 5], o[:, 6] - c.wrist_radius_m * z[:, 6],
                    o[:, 6] + nozzle_end * z[:, 6]], axis=1)
    return start, end
