"""Applies sensor faults to the simulator's readings, by each reading's own stamp.

``FaultInjector`` holds the scheduled faults (``FaultScheduleConfig``) and
those added at run time (``add``), says which are active at a sim time
(``active``) and transforms or drops readings (``gps``, ``camera``,
``lidar``: the reading, a changed copy, or None = dropped). Faults act on a
reading's stamp, not on the moment it leaves the simulator, so pipelined
sensors (``SimulatorConfig.sensor_workers``) see the same faults as serial
ones. The degraded-fix noise of each fault comes from its own generator,
seeded by (schedule seed, the fault's number in the order added): the same
schedule and seed give the same faulty fixes.

How overlapping GPS faults combine: an outage drops the fix; else a no-fix
fault turns it into a NO_FIX message (NaN position, unknown covariance);
else every degraded fault adds its noise and variance (the status is that of
the noisiest one) and every jump adds its offset.

North / east offsets [m] become latitude / longitude through the radii of
curvature of the simulator's geodesy (``HectorGeodesy.radius_north_m`` /
``radius_east_m``), the same flat-earth mapping the hector plugin uses, so an
offset of d metres moves the fix by exactly d metres in the world.
"""
from __future__ import annotations

import dataclasses
import math
from collections import Counter
from typing import List, Optional, Sequence

import numpy as np

from cottonsim_common.validation import require_instance
from cottonsim_world.faults.schedule import (ALL_CAMERAS, FIX_TYPE_STATUS, GPS_KINDS, GPS_STATUS_NO_FIX,
                                             FaultScheduleConfig, FaultSpec)


class _Fault:
    """A fault in the injector: its spec, its (possibly shortened) end and its noise state."""

    __slots__ = ("number", "spec", "end_s", "rng", "noise_m", "last_stamp_s")

    def __init__(self, number: int, spec: FaultSpec, seed: int):
        self.number = number
        self.spec = spec
        self.end_s = spec.end_s
        self.rng = np.random.default_rng((seed, number)) if spec.kind == "gps_degraded" else None
        self.noise_m: Optional[np.ndarray] = None     # degraded: current north, east, up error [m]
        self.last_stamp_s = 0.0

    def active_at(self, stamp_s: float) -> bool:
        return self.spec.start_s <= stamp_s < self.end_s

    def degraded_noise(self, stamp_s: float) -> np.ndarray:
        """The degraded fix's error (north, east, up) [m] at ``stamp_s``: white or Gauss-Markov, std noise_std_m."""
        std, tau = self.spec.noise_std_m, self.spec.correlation_time_s
        n = self.rng.standard_normal(3)
        if self.noise_m is None or tau == 0.0:
            self.noise_m = std * n                    # white, or the wander's stationary start
        else:
            a = math.exp(-max(0.0, stamp_s - self.last_stamp_s) / tau)
            self.noise_m = a * self.noise_m + std * math.sqrt(1.0 - a * a) * n
        self.last_stamp_s = stamp_s
        return self.noise_m


class FaultInjector:
    """Scheduled and run-time sensor faults (see the module docstring).

    cameras: the simulated camera namespaces (a camera_blackout must name one or 'all').
    radius_north_m / radius_east_m: metres per radian of latitude / longitude at the datum
    (``HectorGeodesy``), for the north / east offsets of degraded and jumping fixes.
    ``affected``: readings changed or dropped so far, per fault kind.
    """

    def __init__(self, schedule: FaultScheduleConfig, cameras: Sequence[str], radius_north_m: float,
                 radius_east_m: float):
        require_instance("schedule", schedule, FaultScheduleConfig)
        for name, v in (("radius_north_m", radius_north_m), ("radius_east_m", radius_east_m)):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a radius > 0 [m], got {v!r}")
        schedule.check_cameras(list(cameras))
        self.cameras = tuple(cameras)
        self.seed = schedule.seed
        self._deg_per_m_north = math.degrees(1.0 / radius_north_m)
        self._deg_per_m_east = math.degrees(1.0 / radius_east_m)
        self._faults: List[_Fault] = []
        self._latest_end_s = -math.inf       # no fault acts on stamps at or after this
        self.affected: Counter = Counter()
        for spec in schedule.faults:
            self._append(spec)

    # ------------------------------------------------------------------ the fault list
    def _append(self, spec: FaultSpec) -> int:
        number = len(self._faults)
        self._faults.append(_Fault(number, spec, self.seed))
        self._latest_end_s = max(self._latest_end_s, spec.end_s)
        return number

    def add(self, spec: FaultSpec) -> int:
        """Add a fault (run time); returns its number. ValueError for a camera that is not simulated."""
        if not isinstance(spec, FaultSpec):
            raise ValueError(f"add needs a FaultSpec, got {type(spec).__name__}")
        FaultScheduleConfig((spec,)).check_cameras(list(self.cameras))
        return self._append(spec)

    def clear(self, now_s: float) -> int:
        """End every fault that is active or still to come at sim time ``now_s``; how many were ended."""
        ended = 0
        for f in self._faults:
            if f.end_s > now_s:
                f.end_s = max(f.spec.start_s, now_s)
                ended += 1
        self._latest_end_s = max((f.end_s for f in self._faults), default=-math.inf)
        return ended

    def active(self, stamp_s: float) -> List[FaultSpec]:
        """The faults active at sim time ``stamp_s``, in the order added (ends shortened by ``clear``)."""
        return [dataclasses.replace(f.spec, duration_s=f.end_s - f.spec.start_s) if f.end_s != f.spec.end_s
                else f.spec for f in self._faults if f.active_at(stamp_s)]

    @property
    def idle(self) -> bool:
        """True when no fault was ever added (readings pass untouched at no cost)."""
        return not self._faults

    def ended_by(self, stamp_s: float) -> bool:
        """True when no fault acts on stamps at or after ``stamp_s`` (until another is added)."""
        return stamp_s >= self._latest_end_s

    def _active(self, stamp_s: float, kinds) -> List[_Fault]:
        if stamp_s >= self._latest_end_s:
            return []
        return [f for f in self._faults if f.spec.kind in kinds and f.active_at(stamp_s)]

    # ------------------------------------------------------------------ readings
    def gps(self, reading):
        """A GpsReading (fields stamp_s, latitude_deg, longitude_deg, altitude_m, position_variance_m2,
        status) after the GPS faults at its stamp; None when an outage drops it."""
        faults = self._active(reading.stamp_s, GPS_KINDS)
        if not faults:
            return reading
        kinds = {f.spec.kind for f in faults}
        if "gps_outage" in kinds:
            self.affected["gps_outage"] += 1
            return None
        if "gps_no_fix" in kinds:
            self.affected["gps_no_fix"] += 1
            return dataclasses.replace(reading, latitude_deg=math.nan, longitude_deg=math.nan, altitude_m=math.nan,
                                       position_variance_m2=math.nan, status=GPS_STATUS_NO_FIX)
        north = east = up = 0.0
        variance = reading.position_variance_m2
        status, noisiest = reading.status, -1.0
        for f in faults:
            spec = f.spec
            self.affected[spec.kind] += 1
            if spec.kind == "gps_degraded":
                dn, de, du = f.degraded_noise(reading.stamp_s).tolist()
                north, east, up = north + dn, east + de, up + du
                variance += spec.noise_std_m ** 2
                if spec.noise_std_m > noisiest:
                    status, noisiest = FIX_TYPE_STATUS[spec.fix_type], spec.noise_std_m
            else:                                     # gps_jump
                north += spec.offset_north_m
                east += spec.offset_east_m
        return dataclasses.replace(reading, latitude_deg=reading.latitude_deg + north * self._deg_per_m_north,
                                   longitude_deg=reading.longitude_deg + east * self._deg_per_m_east,
                                   altitude_m=reading.altitude_m + up, position_variance_m2=variance, status=status)

    def _count_and_drop(self, kind: str, faults) -> bool:
        """Count a reading that active ``faults`` of ``kind`` change; True when one of them drops it."""
        self.affected[kind] += 1
        return any(f.spec.mode == "drop" for f in faults)

    def camera(self, reading):
        """A CameraReading (fields stamp_s, camera, frame, cloud_*) after the blackouts of its camera;
        None when one drops it, black pixels and no depth points for mode black."""
        faults = [f for f in self._active(reading.stamp_s, ("camera_blackout",))
                  if f.spec.camera in (ALL_CAMERAS, reading.camera)]
        if not faults:
            return reading
        if self._count_and_drop("camera_blackout", faults):
            return None
        frame = reading.frame
        black = dataclasses.replace(frame, rgb=np.zeros_like(frame.rgb),
                                    depth_m=np.full(frame.depth_m.shape, np.nan, dtype=frame.depth_m.dtype))
        changes = {"frame": black}
        for name in ("cloud_xyz", "cloud_rgb", "cloud_xyzrgb"):
            cloud = getattr(reading, name)
            if cloud is not None:
                changes[name] = cloud[:0]
        return dataclasses.replace(reading, **changes)

    def lidar(self, reading):
        """A LidarReading after the LiDAR dropouts at its stamp: None (drop), or no returns (empty)."""
        faults = self._active(reading.stamp_s, ("lidar_dropout",))
        if not faults:
            return reading
        if self._count_and_drop("lidar_dropout", faults):
            return None
        scan = reading.scan
        empty = dataclasses.replace(scan, **{f.name: getattr(scan, f.name)[:0] for f in dataclasses.fields(scan)})
        return dataclasses.replace(reading, scan=empty, passthrough_points=reading.passthrough_points[:0],
                                   scan_ranges=np.full_like(reading.scan_ranges, np.inf),
                                   scan_360_ranges=np.full_like(reading.scan_360_ranges, np.inf))
