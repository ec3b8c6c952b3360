"""Sensor faults as data: what fails, when, and how (validated).

Why: a simulator for field robots must let users lose the GPS (an RTK fix
drops to float or single under trees, or disappears next to a building),
see multipath jumps, and black out a camera or the LiDAR. A fault is a
:class:`FaultSpec`; the run's list of them is a :class:`FaultScheduleConfig`
(``SimulatorConfig.faults``, the ``faults`` key of config/sim.yaml); the
:class:`~cottonsim_world.faults.injector.FaultInjector` applies them to the
readings.

Kinds and their own keys (every fault has ``kind``, ``start_s`` [s, sim
time] and ``duration_s`` [s, > 0; .inf = until cleared]):

``gps_outage``       no /navsat/fix messages at all.
``gps_no_fix``       fixes keep coming with status NO_FIX (-1), NaN position, covariance unknown.
``gps_degraded``     ``fix_type`` float | sbas | single (status GBAS_FIX 2 | SBAS_FIX 1 | FIX 0),
                     ``noise_std_m`` [m] extra north/east/up noise (default per fix type:
                     :data:`DEGRADED_NOISE_STD_M`), ``correlation_time_s`` [s] of that noise
                     (0 = white, else a first-order Gauss-Markov wander); the fix's covariance
                     (diagonal, known) is the true variance: nominal + noise_std_m^2.
``gps_jump``         multipath: the position jumps by ``offset_north_m`` / ``offset_east_m`` [m]
                     for the duration, status and covariance unchanged (the receiver cannot tell).
``camera_blackout``  ``camera`` (a camera namespace or "all"), ``mode`` black (frames keep coming,
                     every pixel 0, no depth points; ground-truth semantics unchanged) | drop (no
                     messages of that camera).
``lidar_dropout``    ``mode`` drop (no /points, /passthrough/output, /scan, /vlp/scan, /scan_360) |
                     empty (messages keep coming with no returns: empty clouds, every range inf).

A key that does not belong to the fault's kind is refused, naming it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Mapping, Optional, Sequence, Tuple

# NavSatFix status values (sensor_msgs/NavSatStatus), kept here so the core needs no ROS
GPS_STATUS_NO_FIX = -1
GPS_STATUS_FIX = 0
GPS_STATUS_SBAS_FIX = 1
GPS_STATUS_GBAS_FIX = 2

FAULT_KINDS = ("gps_outage", "gps_no_fix", "gps_degraded", "gps_jump", "camera_blackout", "lidar_dropout")
GPS_KINDS = ("gps_outage", "gps_no_fix", "gps_degraded", "gps_jump")
# the keys each kind takes besides kind, start_s and duration_s
KIND_KEYS = {
    "gps_outage": (),
    "gps_no_fix": (),
    "gps_degraded": ("fix_type", "noise_std_m", "correlation_time_s"),
    "gps_jump": ("offset_north_m", "offset_east_m"),
    "camera_blackout": ("camera", "mode"),
    "lidar_dropout": ("mode",),
}
COMMON_KEYS = ("kind", "start_s", "duration_s")
MODES = {"camera_blackout": ("black", "drop"), "lidar_dropout": ("drop", "empty")}
FIX_TYPE_STATUS = {"float": GPS_STATUS_GBAS_FIX, "sbas": GPS_STATUS_SBAS_FIX, "single": GPS_STATUS_FIX}
# default extra noise of a degraded fix [m, 1 sigma per axis]: RTK float, SBAS-corrected, single point
DEGRADED_NOISE_STD_M = {"float": 0.3, "sbas": 1.0, "single": 2.5}
ALL_CAMERAS = "all"


def _number(owner: str, name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
        raise ValueError(f"{owner}.{name} must be a number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class FaultSpec:
    """One sensor fault (see the module docstring for the kinds and their keys).

    start_s [s]: sim time at which it begins (>= 0); duration_s [s]: how long (> 0, inf = until
    cleared); it is active for stamps in [start_s, start_s + duration_s). The kind-specific keys
    left at their defaults ("" / None / 0) take the kind's defaults; a kind-specific key set for
    another kind is refused.
    """

    kind: str
    start_s: float = 0.0
    duration_s: float = math.inf
    fix_type: str = ""
    noise_std_m: Optional[float] = None
    correlation_time_s: float = 0.0
    offset_north_m: float = 0.0
    offset_east_m: float = 0.0
    camera: str = ""
    mode: str = ""

    def __post_init__(self) -> None:
        owner = "FaultSpec"
        if self.kind not in FAULT_KINDS:
            raise ValueError(f"{owner}.kind must be one of {', '.join(FAULT_KINDS)}; got {self.kind!r}")
        owner = f"fault {self.kind}"
        start = _number(owner, "start_s", self.start_s)
        if not (math.isfinite(start) and start >= 0.0):
            raise ValueError(f"{owner}.start_s must be a finite sim time >= 0 [s], got {self.start_s!r}")
        duration = _number(owner, "duration_s", self.duration_s)
        if not duration > 0.0:
            raise ValueError(f"{owner}.duration_s must be > 0 [s] (.inf = until cleared), got {self.duration_s!r}")
        object.__setattr__(self, "start_s", start)
        object.__setattr__(self, "duration_s", duration)
        own = KIND_KEYS[self.kind]
        defaults = {f.name: f.default for f in fields(self)}
        for name in ("fix_type", "noise_std_m", "correlation_time_s", "offset_north_m", "offset_east_m",
                     "camera", "mode"):
            if name not in own and getattr(self, name) != defaults[name]:
                raise ValueError(f"{owner}: key '{name}' does not apply to {self.kind} "
                                 f"(its keys: {', '.join(COMMON_KEYS + own)})")
        if self.kind == "gps_degraded":
            fix_type = self.fix_type or "float"
            if fix_type not in FIX_TYPE_STATUS:
                raise ValueError(f"{owner}.fix_type must be one of {', '.join(FIX_TYPE_STATUS)}, got {self.fix_type!r}")
            object.__setattr__(self, "fix_type", fix_type)
            std = DEGRADED_NOISE_STD_M[fix_type] if self.noise_std_m is None else \
                _number(owner, "noise_std_m", self.noise_std_m)
            if not (math.isfinite(std) and std >= 0.0):
                raise ValueError(f"{owner}.noise_std_m must be a finite std >= 0 [m], got {self.noise_std_m!r}")
            object.__setattr__(self, "noise_std_m", std)
            tau = _number(owner, "correlation_time_s", self.correlation_time_s)
            if not (math.isfinite(tau) and tau >= 0.0):
                raise ValueError(f"{owner}.correlation_time_s must be finite and >= 0 [s] (0 = white), "
                                 f"got {self.correlation_time_s!r}")
            object.__setattr__(self, "correlation_time_s", tau)
        if self.kind == "gps_jump":
            north = _number(owner, "offset_north_m", self.offset_north_m)
            east = _number(owner, "offset_east_m", self.offset_east_m)
            if not (math.isfinite(north) and math.isfinite(east)):
                raise ValueError(f"{owner}: offset_north_m / offset_east_m must be finite [m]")
            if north == 0.0 and east == 0.0:
                raise ValueError(f"{owner}: a jump needs offset_north_m or offset_east_m != 0 [m]")
            object.__setattr__(self, "offset_north_m", north)
            object.__setattr__(self, "offset_east_m", east)
        if self.kind in MODES:
            mode = self.mode or MODES[self.kind][0]
            if mode not in MODES[self.kind]:
                raise ValueError(f"{owner}.mode must be one of {', '.join(MODES[self.kind])}, got {self.mode!r}")
            object.__setattr__(self, "mode", mode)
        if self.kind == "camera_blackout":
            camera = self.camera or ALL_CAMERAS
            if not isinstance(camera, str):
                raise ValueError(f"{owner}.camera must be a camera namespace or '{ALL_CAMERAS}', got {camera!r}")
            object.__setattr__(self, "camera", camera)

    @property
    def end_s(self) -> float:
        """Sim time [s] at which the fault is over (inf = until cleared)."""
        return self.start_s + self.duration_s

    def active_at(self, stamp_s: float) -> bool:
        return self.start_s <= stamp_s < self.end_s

    @property
    def target(self) -> str:
        """The sensor it hits: gps, lidar or the camera namespace ('all' for every camera)."""
        if self.kind in GPS_KINDS:
            return "gps"
        if self.kind == "lidar_dropout":
            return "lidar"
        return self.camera

    def parameters(self) -> dict:
        """Its kind-specific settings after defaults (for the active-faults topic and logs)."""
        return {name: getattr(self, name) for name in KIND_KEYS[self.kind]}

    def describe(self) -> str:
        params = ", ".join(f"{k}={v}" for k, v in self.parameters().items())
        return (f"{self.kind} on {self.target} from {self.start_s:.2f} s for "
                f"{'ever' if math.isinf(self.duration_s) else f'{self.duration_s:.2f} s'}"
                + (f" ({params})" if params else ""))


def fault_from_mapping(mapping: Mapping[str, Any], where: str = "fault") -> FaultSpec:
    """A FaultSpec from a dict shaped like a config/sim.yaml ``faults`` entry; errors name ``where``."""
    if not isinstance(mapping, Mapping):
        raise ValueError(f"{where} must be a mapping with kind, start_s, duration_s, ...; got {mapping!r}")
    kind = mapping.get("kind")
    if kind not in FAULT_KINDS:
        raise ValueError(f"{where}.kind must be one of {', '.join(FAULT_KINDS)}; got {kind!r}")
    allowed = COMMON_KEYS + KIND_KEYS[kind]
    missing = [k for k in ("start_s", "duration_s") if k not in mapping]
    if missing:
        raise ValueError(f"{where} ({kind}) lacks {' and '.join(missing)} [s] (duration_s .inf = until cleared)")
    unknown = [str(k) for k in mapping if k not in allowed]
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)} for {kind} (its keys: {', '.join(allowed)})")
    try:
        return FaultSpec(**{str(k): v for k, v in mapping.items()})
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


@dataclass(frozen=True)
class FaultScheduleConfig:
    """The run's scheduled sensor faults (default: none) and the seed of their noise.

    faults: FaultSpec entries, in any order; several may overlap (see FaultInjector for how
    they combine). seed: seed of the degraded-fix noise; SimulatorConfig replaces it by one
    derived from its own seed.
    """

    faults: Tuple[FaultSpec, ...] = ()
    seed: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.faults, (tuple, list)):
            raise ValueError(f"FaultScheduleConfig.faults must be a list of faults, got {self.faults!r}")
        for i, f in enumerate(self.faults):
            if not isinstance(f, FaultSpec):
                raise ValueError(f"FaultScheduleConfig.faults[{i}] must be a FaultSpec, got {type(f).__name__}")
        object.__setattr__(self, "faults", tuple(self.faults))
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"FaultScheduleConfig.seed must be an int >= 0, got {self.seed!r}")

    def check_cameras(self, cameras: Sequence[str]) -> None:
        """ValueError when a camera_blackout names a camera that is not simulated."""
        for i, f in enumerate(self.faults):
            if f.kind == "camera_blackout" and f.camera != ALL_CAMERAS and f.camera not in cameras:
                raise ValueError(f"faults[{i}].camera {f.camera!r} is not a simulated camera "
                                 f"(simulated: {', '.join(cameras) or 'none'}; or '{ALL_CAMERAS}')")


def fault_schedule_from_list(entries: Any, seed: int = 0) -> FaultScheduleConfig:
    """FaultScheduleConfig from the ``faults`` list of config/sim.yaml (None or [] = no faults)."""
    if entries is None:
        entries = []
    if isinstance(entries, Mapping) or not isinstance(entries, (list, tuple)):
        raise ValueError(f"config key 'faults' must be a list of faults (each a mapping with kind, start_s, "
                         f"duration_s, ...), got {entries!r}")
    return FaultScheduleConfig(tuple(fault_from_mapping(e, f"faults[{i}]") for i, e in enumerate(entries)), seed)
