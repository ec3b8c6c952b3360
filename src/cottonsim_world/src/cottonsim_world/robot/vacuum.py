"""The vacuum nozzle on the UR5e's flange: captures, carries and releases bolls.

The simulation models no air flow: while the vacuum is on and the nozzle
holds nothing, the nozzle captures the nearest open boll when the capture
rule of cottonsim_common.vacuum_capture holds (tip within
``capture_radius_m`` of the boll's centre, the nozzle axis within
``cone_half_angle_rad`` of the boll's inward direction); the boll leaves its
plant (``BollStore.attach``) and from then on travels with the tool (its
offset from the tip, in the tip frame, stays what it was at the capture).
Switching the vacuum off releases the held boll: into the bin when the tip
is inside the bin's opening (a box in base_link, ``bin_centre_m`` +-
``bin_half_size_m``), else it is dropped where it is. Switching it off with
nothing held says why nothing was captured: the closest the tip came to an
open boll while the vacuum was on, with its distance and angle. The tip frame is the
URDF's ur5e_nozzle_tip (z along the nozzle, out of it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from cottonsim_common.vacuum_capture import CaptureCheck, CaptureConfig, check_capture
from cottonsim_world.robot.boll_store import BollStore


def _triple(config, name: str, positive: bool) -> None:
    v = getattr(config, name)
    ok = isinstance(v, tuple) and len(v) == 3 and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and (x > 0 or not positive)
        for x in v)
    if not ok:
        raise ValueError(f"VacuumConfig.{name} must be 3 finite numbers{' > 0' if positive else ''} [m], got {v!r}")


@dataclass(frozen=True)
class VacuumConfig:
    """The vacuum nozzle (sim.yaml 'vacuum').

    capture_radius_m: largest tip-to-boll-centre distance that captures [m].
    cone_half_angle_rad: largest angle between the nozzle axis and the boll's inward direction [rad].
    bin_centre_m, bin_half_size_m: the bin's opening as a box in base_link [m]: a boll released with
        the tip inside it falls into the bin. Default: inside the walls of the URDF's cotton_bin (on the
        control box, rim at z 0.515 m) from 4.5 cm below the rim to 17.5 cm above it.
    """

    capture_radius_m: float = 0.02
    cone_half_angle_rad: float = math.radians(45.0)
    bin_centre_m: Tuple[float, float, float] = (-0.065, 0.0, 0.58)
    bin_half_size_m: Tuple[float, float, float] = (0.10, 0.19, 0.11)

    def __post_init__(self) -> None:
        try:
            self.capture_rule()
        except ValueError as exc:
            raise ValueError(str(exc).replace("CaptureConfig", "VacuumConfig")) from None
        _triple(self, "bin_centre_m", positive=False)
        _triple(self, "bin_half_size_m", positive=True)

    def capture_rule(self) -> CaptureConfig:
        return CaptureConfig(self.capture_radius_m, self.cone_half_angle_rad)


class VacuumNozzle:
    """Vacuum state, the held boll and the capture rule applied to a BollStore (see the module docstring)."""

    def __init__(self, store: BollStore, config: VacuumConfig = VacuumConfig()):
        self.store = store
        self.config = config
        self._rule = config.capture_rule()
        self.on = False
        self.held_id: Optional[int] = None
        self._tip_T_boll: Optional[np.ndarray] = None
        self._closest: Optional[Tuple[int, CaptureCheck]] = None   # (boll id, check) of this vacuum-on, no capture

    def switch(self, on: bool, world_T_tip: np.ndarray, world_T_base: np.ndarray) -> str:
        """Turn the vacuum on or off (off releases a held boll); returns what happened, in words."""
        self.on = bool(on)
        if self.on:
            self._closest = None
            return "vacuum on" + (f", holding boll {self.held_id}" if self.held_id is not None else "")
        if self.held_id is None:
            return "vacuum off" + self._miss_summary()
        boll, self.held_id = self.held_id, None
        tip_in_base = np.linalg.solve(world_T_base, world_T_tip)[:3, 3]
        offset = np.abs(tip_in_base - np.asarray(self.config.bin_centre_m))
        if np.all(offset <= np.asarray(self.config.bin_half_size_m)):
            self.store.release_into_bin(boll)
            return f"vacuum off: boll {boll} released into the bin"
        self.store.drop(boll, (world_T_tip @ self._tip_T_boll)[:3, 3])
        return f"vacuum off: boll {boll} dropped outside the bin, tip at {np.round(tip_in_base, 3).tolist()} m in " \
               f"base_link"

    def step(self, world_T_tip: np.ndarray) -> Optional[int]:
        """Apply the capture rule (vacuum on, nothing held) or carry the held boll; the id captured now, if any."""
        if self.held_id is not None:
            self.store.carry(self.held_id, (world_T_tip @ self._tip_T_boll)[:3, 3])
            return None
        if not self.on:
            return None
        tip, axis = world_T_tip[:3, 3], world_T_tip[:3, 2]
        boll = self.store.nearest_open(tip)
        if boll is None:
            return None
        check = check_capture(tip, axis, boll.centre_m, boll.outward, self._rule)
        if not check.captured:
            if self._closest is None or check.distance_m < self._closest[1].distance_m:
                self._closest = (boll.boll_id, check)
            return None
        self.store.attach(boll.boll_id)
        self.held_id = boll.boll_id
        boll_pose = np.eye(4)
        boll_pose[:3, 3] = boll.centre_m
        self._tip_T_boll = np.linalg.solve(world_T_tip, boll_pose)
        return boll.boll_id

    def _miss_summary(self) -> str:
        """Why the vacuum-on that ends now captured nothing: its closest approach to an open boll."""
        if self._closest is None:
            return ""
        boll_id, check = self._closest
        self._closest = None
        return (f": nothing captured; the tip came within {check.distance_m * 1e3:.1f} mm of boll {boll_id}, "
                f"{math.degrees(check.angle_rad):.0f} deg off its inward direction ({check.reason.replace('_', ' ')}: "
                f"capture radius {self._rule.capture_radius_m * 1e3:.0f} mm, cone "
                f"{math.degrees(self._rule.cone_half_angle_rad):.0f} deg)")
