"""IMU measurement model: true body motion -> noisy, drifting /imu/data.

The original CottonSim (like Clearpath's Husky simulation) used the hector
IMU plugin at 50 Hz with Gaussian noise and bias drift of 0.005 on rates,
accelerations and heading. We keep that structure: each channel is

    measured = true + bias + white noise,

where the bias is a first-order Gauss-Markov process (stationary standard
deviation ``*_drift``, correlation time ``drift_time_s``) that starts at
zero, as hector's sensor model does. Roll and pitch get white noise only,
yaw gets noise plus its own drift, so a heading from the IMU slowly wanders
while tilt stays honest (a gravity-aided AHRS).

The model is deterministic per seed (numpy Generator) and refuses
non-finite inputs with a ValueError naming the field; its internal state is
not advanced by a refused sample.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

from cottonsim_common.validation import require_fields


@dataclass(frozen=True)
class ImuConfig:
    """Noise parameters of the simulated IMU.

    rate_hz: output rate [Hz] (the caller schedules; see ``period_s``).
    gyro_noise_rad_s / gyro_drift_rad_s: white noise std and bias std of the
        angular velocity [rad/s].
    accel_noise_m_s2 / accel_drift_m_s2: same for the linear acceleration
        [m/s^2].
    orientation_noise_rad: white noise std on roll, pitch, yaw [rad];
    yaw_drift_rad: bias std of the yaw [rad].
    drift_time_s: correlation time of every bias [s] (hector: 3600 s).
    seed: random seed.
    """

    rate_hz: float = 50.0
    gyro_noise_rad_s: float = 0.005
    gyro_drift_rad_s: float = 0.005
    accel_noise_m_s2: float = 0.005
    accel_drift_m_s2: float = 0.005
    orientation_noise_rad: float = 0.005
    yaw_drift_rad: float = 0.005
    drift_time_s: float = 3600.0
    seed: int = 0

    def __post_init__(self) -> None:
        require_fields(self, "ImuConfig.", positive=("rate_hz", "drift_time_s"),
                       non_negative=("gyro_noise_rad_s", "gyro_drift_rad_s", "accel_noise_m_s2", "accel_drift_m_s2",
                                     "orientation_noise_rad", "yaw_drift_rad"))
        if not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"ImuConfig.seed must be an int >= 0, got {self.seed!r}")


@dataclass(frozen=True)
class ImuMeasurement:
    """One IMU sample in the IMU (= base_link) axes.

    orientation_xyzw: attitude quaternion; angular_velocity_rad_s (3,);
    linear_acceleration_m_s2 (3,) (specific force, +9.8 z at rest);
    *_covariance: 3x3 row-major as sensor_msgs/Imu wants (9,).
    """

    stamp_s: float
    orientation_xyzw: np.ndarray
    angular_velocity_rad_s: np.ndarray
    linear_acceleration_m_s2: np.ndarray
    orientation_covariance: np.ndarray
    angular_velocity_covariance: np.ndarray
    linear_acceleration_covariance: np.ndarray


def _quat_to_rpy_floats(x: float, y: float, z: float, w: float) -> Tuple[float, float, float]:
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def quat_to_rpy(q_xyzw: Sequence[float]) -> np.ndarray:
    """Roll, pitch, yaw [rad] (ZYX convention) of a quaternion (x, y, z, w)."""
    x, y, z, w = q_xyzw
    return np.array(_quat_to_rpy_floats(x, y, z, w))


def rpy_to_quat(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Quaternion (x, y, z, w) of roll, pitch, yaw [rad] (ZYX convention)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return np.array([sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy,
                     cr * cp * cy + sr * sp * sy])


def _finite_vector(value, n: int, name: str) -> List[float]:
    """value as n finite Python floats, or a ValueError naming the input."""
    if isinstance(value, np.ndarray) and value.dtype == np.float64:
        values = value.reshape(-1).tolist()
    else:
        try:
            values = [float(v) for v in value]
        except (TypeError, ValueError):
            try:
                values = np.asarray(value, dtype=float).reshape(-1).tolist()
            except (TypeError, ValueError) as exc:
                raise ValueError(f"IMU input {name} must be {n} numbers, got {value!r}") from exc
    if len(values) != n:
        raise ValueError(f"IMU input {name} must have {n} values, got shape {np.shape(value)}")
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"IMU input {name} contains NaN or inf: {values}")
    return values


class ImuModel:
    """Turns the true state into IMU samples with noise and bias drift.

    It runs at 50 Hz on 3-vectors, so the arithmetic is on plain floats
    (numpy's per-call overhead would dominate); the random numbers come
    from one numpy Generator in the same order as element-wise draws.
    """

    def __init__(self, config: ImuConfig = ImuConfig()):
        self.config = config
        self._rng = np.random.default_rng(config.seed)
        self._gyro_bias = [0.0, 0.0, 0.0]
        self._accel_bias = [0.0, 0.0, 0.0]
        self._yaw_bias = 0.0
        self._last_stamp_s: Optional[float] = None
        c = config
        self._orientation_cov = np.diag([c.orientation_noise_rad ** 2] * 2
                                        + [c.orientation_noise_rad ** 2 + c.yaw_drift_rad ** 2]).reshape(-1)
        self._gyro_cov = (np.eye(3) * (c.gyro_noise_rad_s ** 2 + c.gyro_drift_rad_s ** 2)).reshape(-1)
        self._accel_cov = (np.eye(3) * (c.accel_noise_m_s2 ** 2 + c.accel_drift_m_s2 ** 2)).reshape(-1)

    @property
    def period_s(self) -> float:
        return 1.0 / self.config.rate_hz

    @property
    def biases(self) -> dict:
        """Current biases (for tests and diagnostics)."""
        return {"gyro_rad_s": np.array(self._gyro_bias), "accel_m_s2": np.array(self._accel_bias),
                "yaw_rad": self._yaw_bias}

    def measure(self, stamp_s: float, orientation_xyzw, angular_velocity_body_rad_s,
                linear_acceleration_body_m_s2) -> ImuMeasurement:
        """One sample at stamp_s [s] from the true state (base_link axes)."""
        if not isinstance(stamp_s, (int, float)) or not math.isfinite(stamp_s):
            raise ValueError(f"IMU input stamp_s must be finite, got {stamp_s!r}")
        qx, qy, qz, qw = _finite_vector(orientation_xyzw, 4, "orientation_xyzw")
        norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        if norm < 1e-9:
            raise ValueError("IMU input orientation_xyzw is a zero quaternion")
        gyro = _finite_vector(angular_velocity_body_rad_s, 3, "angular_velocity_body_rad_s")
        acc = _finite_vector(linear_acceleration_body_m_s2, 3, "linear_acceleration_body_m_s2")
        if self._last_stamp_s is not None and stamp_s < self._last_stamp_s:
            raise ValueError(f"IMU input stamp_s went backwards ({stamp_s} < {self._last_stamp_s})")
        dt = 0.0 if self._last_stamp_s is None else stamp_s - self._last_stamp_s
        self._last_stamp_s = float(stamp_s)
        c = self.config
        # One draw per sample; the order is that of the former per-field draws:
        # gyro bias (3), accel bias (3), yaw bias (1) when time advanced, then
        # orientation (3), gyro (3) and accel (3) white noise.
        if dt > 0.0:
            z = self._rng.standard_normal(16).tolist()
            # first-order Gauss-Markov bias: b' = phi b + sqrt(1 - phi^2) std n
            phi = math.exp(-dt / c.drift_time_s)
            root = math.sqrt(max(0.0, 1.0 - phi * phi))
            g, a = root * c.gyro_drift_rad_s, root * c.accel_drift_m_s2
            self._gyro_bias = [phi * b + g * n for b, n in zip(self._gyro_bias, z[0:3])]
            self._accel_bias = [phi * b + a * n for b, n in zip(self._accel_bias, z[3:6])]
            self._yaw_bias = phi * self._yaw_bias + root * c.yaw_drift_rad * z[6]
            z = z[7:]
        else:
            z = self._rng.standard_normal(9).tolist()
        roll, pitch, yaw = _quat_to_rpy_floats(qx / norm, qy / norm, qz / norm, qw / norm)
        sigma = c.orientation_noise_rad
        roll += sigma * z[0]
        pitch += sigma * z[1]
        yaw = (yaw + sigma * z[2] + self._yaw_bias + math.pi) % (2.0 * math.pi) - math.pi
        gn, an = c.gyro_noise_rad_s, c.accel_noise_m_s2
        return ImuMeasurement(
            stamp_s=float(stamp_s),
            orientation_xyzw=rpy_to_quat(roll, pitch, yaw),
            angular_velocity_rad_s=np.array([v + b + gn * n for v, b, n in zip(gyro, self._gyro_bias, z[3:6])]),
            linear_acceleration_m_s2=np.array([v + b + an * n for v, b, n in zip(acc, self._accel_bias, z[6:9])]),
            orientation_covariance=self._orientation_cov.copy(),
            angular_velocity_covariance=self._gyro_cov.copy(),
            linear_acceleration_covariance=self._accel_cov.copy(),
        )
