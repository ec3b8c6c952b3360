"""GPS geodesy of the hector_gazebo GPS plugin, and its drift/noise model.

Why: the original CottonSim simulated GPS with hector_gazebo_plugins'
``GazeboRosGps``. That plugin does not project on an ellipsoid; it uses a
local flat-earth approximation around a reference point, with the WGS84
radii of curvature at the reference latitude:

    e2  = f (2 - f)                              (WGS84 a = 6378137 m, f = 1/298.257223563)
    N   = a / sqrt(1 - e2 sin^2(lat0))           (prime vertical radius)
    R_N = N (1 - e2) / (1 - e2 sin^2(lat0))      (meridian radius; 6,372,845 m at 49.9 deg)
    R_E = N cos(lat0)                            (radius of the parallel; 4,116,378 m at 49.9 deg)

    lat = lat0 + deg( ( cos(h) x + sin(h) y) / R_N )
    lon = lon0 - deg( (-sin(h) x + cos(h) y) / R_E )
    alt = alt0 + z

with h the reference heading. With h = 0 world x points north and world y
west (the original's setting); with h = 90 deg x points east and y north
(ENU). Longitudes are wrapped into [-180, 180] deg (a farm on the
antimeridian), differences back into (-180, 180] for the inverse. ``HectorGeodesy`` implements this mapping and its exact inverse,
vectorised over numpy arrays.

``GpsNoiseModel`` reproduces the plugin's error model (a per-axis offset, a
slowly wandering drift and white Gaussian noise, in metres in the world
frame) deterministically from a seed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Tuple, Union

import numpy as np

from cottonsim_common.validation import require_finite_array, require_finite_values, require_instance

WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563

ArrayLike = Union[float, np.ndarray]


def _out(*arrays: np.ndarray, scalar: bool):
    if scalar:
        return tuple(float(a) for a in arrays)
    return arrays


class HectorGeodesy:
    """World <-> geodetic mapping of hector_gazebo's GPS plugin.

    Args (degrees / metres): reference_latitude_deg, reference_longitude_deg,
    reference_altitude_m, reference_heading_deg (see the module docstring).
    Defaults are the original CottonSim's reference (49.9, 8.9, 0, 0).
    """

    def __init__(self, reference_latitude_deg: float = 49.9, reference_longitude_deg: float = 8.9,
                 reference_altitude_m: float = 0.0, reference_heading_deg: float = 0.0) -> None:
        for name, v in (("reference_latitude_deg", reference_latitude_deg),
                        ("reference_longitude_deg", reference_longitude_deg),
                        ("reference_altitude_m", reference_altitude_m),
                        ("reference_heading_deg", reference_heading_deg)):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v):
                raise ValueError(f"{name} must be a finite number, got {v!r}")
        if abs(reference_latitude_deg) >= 89.9:
            raise ValueError(f"reference_latitude_deg must be within +/-89.9 deg (the east radius vanishes at the poles), got {reference_latitude_deg}")
        if not -180.0 <= reference_longitude_deg <= 180.0:
            raise ValueError(f"reference_longitude_deg must be in [-180, 180], got {reference_longitude_deg}")
        self.reference_latitude_deg = float(reference_latitude_deg)
        self.reference_longitude_deg = float(reference_longitude_deg)
        self.reference_altitude_m = float(reference_altitude_m)
        self.reference_heading_deg = float(reference_heading_deg)
        lat0 = math.radians(self.reference_latitude_deg)
        e2 = WGS84_F * (2.0 - WGS84_F)
        w = 1.0 - e2 * math.sin(lat0) ** 2
        prime_vertical = WGS84_A_M / math.sqrt(w)
        self.radius_north_m = prime_vertical * (1.0 - e2) / w
        self.radius_east_m = prime_vertical * math.cos(lat0)
        h = math.radians(self.reference_heading_deg)
        self._cos_h, self._sin_h = math.cos(h), math.sin(h)

    def world_to_geodetic(self, x_m: ArrayLike, y_m: ArrayLike, z_m: ArrayLike = 0.0):
        """World position [m] -> (latitude [deg], longitude [deg], altitude [m]).

        Scalars in -> floats out; arrays broadcast and give arrays.
        Three floats (the simulator's 40 Hz fix) take a plain-float path with
        the same operations in the same order, so the same result bit for bit
        at a tenth of numpy's per-call cost.
        """
        if isinstance(x_m, float) and isinstance(y_m, float) and isinstance(z_m, float):
            for name, v in (("x_m", x_m), ("y_m", y_m), ("z_m", z_m)):
                if not math.isfinite(v):
                    raise ValueError(f"{name} contains NaN or infinite values")
            x, y = float(x_m), float(y_m)
            north = self._cos_h * x + self._sin_h * y
            west = -self._sin_h * x + self._cos_h * y
            lon = self.reference_longitude_deg - math.degrees(west / self.radius_east_m)
            if not -180.0 <= lon <= 180.0:
                lon = (lon + 180.0) % 360.0 - 180.0
            return (self.reference_latitude_deg + math.degrees(north / self.radius_north_m), lon,
                    self.reference_altitude_m + float(z_m))
        scalar = all(np.ndim(v) == 0 for v in (x_m, y_m, z_m))
        x = require_finite_array("x_m", x_m)
        y = require_finite_array("y_m", y_m)
        z = require_finite_array("z_m", z_m)
        north = self._cos_h * x + self._sin_h * y
        west = -self._sin_h * x + self._cos_h * y
        lat = self.reference_latitude_deg + np.degrees(north / self.radius_north_m)
        lon = self.reference_longitude_deg - np.degrees(west / self.radius_east_m)
        lon = np.where((lon < -180.0) | (lon > 180.0), (lon + 180.0) % 360.0 - 180.0, lon)
        alt = self.reference_altitude_m + z
        lat, lon, alt = np.broadcast_arrays(lat, lon, alt)
        return _out(lat, lon, alt, scalar=scalar)

    def geodetic_to_world(self, latitude_deg: ArrayLike, longitude_deg: ArrayLike, altitude_m: ArrayLike = 0.0):
        """(latitude [deg], longitude [deg], altitude [m]) -> world (x, y, z) [m]."""
        scalar = all(np.ndim(v) == 0 for v in (latitude_deg, longitude_deg, altitude_m))
        lat = require_finite_array("latitude_deg", latitude_deg)
        lon = require_finite_array("longitude_deg", longitude_deg)
        alt = require_finite_array("altitude_m", altitude_m)
        if np.any(np.abs(lat) > 90.0):
            raise ValueError("latitude_deg must be within [-90, 90]")
        north = np.radians(lat - self.reference_latitude_deg) * self.radius_north_m
        dlon = lon - self.reference_longitude_deg
        dlon = np.where(np.abs(dlon) > 180.0, dlon - 360.0 * np.round(dlon / 360.0), dlon)
        west = -np.radians(dlon) * self.radius_east_m
        # invert the rotation [north; west] = [[c, s], [-s, c]] [x; y]
        x = self._cos_h * north - self._sin_h * west
        y = self._sin_h * north + self._cos_h * west
        z = alt - self.reference_altitude_m
        x, y, z = np.broadcast_arrays(x, y, z)
        return _out(x, y, z, scalar=scalar)


@dataclass(frozen=True)
class GpsNoiseConfig:
    """Error model of the simulated GPS (hector_gazebo's SensorModel), per axis x, y, z.

    offset_m: constant bias [m].
    drift_m: standard deviation of the slowly wandering drift [m]
        (the original: 0.0001 m on every axis).
    drift_frequency_hz: inverse correlation time of the drift [1/s]
        (hector's default 1/3600 s^-1).
    gaussian_noise_m: standard deviation of white noise per fix [m] (original: 0).
    seed: random seed; same seed and same sequence of calls -> same errors.

    The drift is a first-order Gauss-Markov (Ornstein-Uhlenbeck) process,
    sampled exactly for any time step: d <- d exp(-f dt) +
    drift_m sqrt(1 - exp(-2 f dt)) N(0, 1), so its standard deviation stays
    ``drift_m`` (hector integrates the same process with an Euler step).
    """

    offset_m: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    drift_m: Tuple[float, float, float] = (0.0001, 0.0001, 0.0001)
    drift_frequency_hz: Tuple[float, float, float] = (1.0 / 3600.0,) * 3
    gaussian_noise_m: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("offset_m", "drift_m", "drift_frequency_hz", "gaussian_noise_m"):
            value = getattr(self, name)
            if np.ndim(value) == 0:
                value = (value,) * 3
            low = -math.inf if name == "offset_m" else 0.0
            object.__setattr__(self, name, require_finite_values(f"{name} (x, y, z)", value, 3, low))
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")


class GpsNoiseModel:
    """Turns true world positions into noisy GPS positions over time.

    Usage: ``noisy_xyz = model.apply(true_xyz, dt_s)`` once per fix, with
    ``dt_s`` the time since the previous fix [s]; convert the result with
    ``HectorGeodesy.world_to_geodetic``. ``reset()`` restarts the sequence.
    """

    def __init__(self, config: GpsNoiseConfig = GpsNoiseConfig()) -> None:
        require_instance("config", config, GpsNoiseConfig)
        self.config = config
        self._offset = tuple(config.offset_m)
        self._freq = np.array(config.drift_frequency_hz)
        self._drift_std = np.array(config.drift_m)
        self._noise = tuple(config.gaussian_noise_m)
        # the drift's decay and innovation gain per axis for the last time step (the fix rate's
        # step repeats): (dt_s, decay (3,), gain (3,)) as plain floats
        self._step_cache: Tuple[float, Tuple[float, ...], Tuple[float, ...]] = (math.nan, (), ())
        self.reset()

    def reset(self) -> None:
        """Restart the random sequence; the drift starts at zero as in hector."""
        self._rng = np.random.default_rng(self.config.seed)
        self._drift = (0.0, 0.0, 0.0)

    @property
    def current_drift_m(self) -> np.ndarray:
        """The drift now (3,) [m] (a copy)."""
        return np.array(self._drift)

    def _errors(self, dt_s: float) -> Tuple[float, float, float]:
        """Advance the drift by dt_s [s]; the error per axis [m] as floats.

        Plain floats, one multiply or add at a time as numpy did them on
        3-vectors (the same results bit for bit); exp and sqrt stay numpy's
        and are cached per time step.
        """
        if isinstance(dt_s, bool) or not isinstance(dt_s, (int, float, np.floating, np.integer)) \
                or not math.isfinite(dt_s) or dt_s < 0:
            raise ValueError(f"dt_s must be a finite number >= 0, got {dt_s!r}")
        cached_dt, decay, gain = self._step_cache
        if dt_s != cached_dt:
            d = np.exp(-self._freq * dt_s)
            decay, gain = tuple(d.tolist()), tuple((self._drift_std * np.sqrt(1.0 - d ** 2)).tolist())
            self._step_cache = (dt_s, decay, gain)
        n1 = self._rng.standard_normal(3).tolist()
        drift = tuple(c * k + g * n for c, k, g, n in zip(self._drift, decay, gain, n1))
        self._drift = drift
        n2 = self._rng.standard_normal(3).tolist()
        return tuple(o + c + s * n for o, c, s, n in zip(self._offset, drift, self._noise, n2))

    def update(self, dt_s: float) -> np.ndarray:
        """Advance the drift by ``dt_s`` seconds; returns the error (3,) [m]."""
        return np.array(self._errors(dt_s))

    def apply(self, position_m, dt_s: float) -> np.ndarray:
        """True world position (3,) [m] -> noisy position (3,) [m]."""
        if isinstance(position_m, np.ndarray) and position_m.shape == (3,) and position_m.dtype == np.float64:
            px, py, pz = position_m.tolist()          # the simulator's case: no numpy round trip
            if not (math.isfinite(px) and math.isfinite(py) and math.isfinite(pz)):
                raise ValueError("position_m contains NaN or infinite values")
        else:
            p = require_finite_array("position_m", position_m)
            if p.shape != (3,):
                raise ValueError(f"position_m must have shape (3,), got {p.shape}")
            px, py, pz = p.tolist()
        ex, ey, ez = self._errors(dt_s)
        return np.array((px + ex, py + ey, pz + ez))
