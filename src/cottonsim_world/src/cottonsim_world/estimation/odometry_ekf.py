"""Planar EKF fusing wheel odometry and IMU: the Husky's /odometry/filtered.

Clearpath runs robot_localization's ekf_localization_node on the Husky
(husky_control/config/localization.yaml): two_d_mode, 50 Hz, world_frame =
odom, fusing the wheel odometry's forward speed and yaw rate and the IMU's
yaw rate (optionally its yaw). This class is that filter cut down to the
states a planar robot needs:

    state s = [x, y, yaw, vx, vyaw]    (odom frame; vx, vyaw in base_link)

Motion model (constant velocity, over dt):
    x += vx cos(yaw) dt,  y += vx sin(yaw) dt,  yaw += vyaw dt
with process noise ``process_noise_diag * dt`` (robot_localization scales
its process noise by dt the same way). Each measurement is linear in the
state (it picks vx, vyaw or yaw), so the update is a standard Kalman update
with the yaw innovation wrapped to (-pi, pi].

Wheel slip (not in robot_localization): when a plant pins the robot, its
wheels spin on while it stands, and wheel odometry runs away. The filter
keeps a second forward speed, ``v_imu``, integrated from the IMU's forward
acceleration (its specific force with gravity removed using its attitude)
and pulled towards the wheel speed with time constant ``slip_blend_time_s``
while the two agree; while slipping it is kept between 0 and the wheel speed
(a robot moves no faster than its wheels turn, nor against them), which
bounds its drift and ends the slip once the wheels stop. When they differ by more than
``slip_speed_threshold_m_s`` the wheels are slipping: ``v_imu`` is then
integrated from the IMU alone and fused as the forward speed (variance
``slip_speed_variance_m2_s2``) instead of the wheels', whose yaw rate is
down-weighted by ``slip_yaw_rate_variance_scale`` too. Slipping ends when the
two agree within half the threshold again. A pinned robot decelerates
against the plant (the IMU sees it), so its speed stays near zero in the
filter although the wheels turn. No IMU acceleration (``update_imu``
without ``accel_body_m_s2``) = no slip check.

Standstill (not in robot_localization; what a robot that stands for minutes, e.g. to pick, needs): the
IMU's gyro has a slowly drifting bias (physics.imu_model), and the filter trusts the gyro's yaw rate far
more than the wheels' (variance 5e-5 against 0.03), so a standing robot's odom yaw ran away with the bias
(0.38 rad in 8 minutes of picking measured). While the wheels stand (forward speed within
``standstill_speed_m_s``, yaw rate within ``standstill_yaw_rate_rad_s``, not slipping): their zero yaw
rate is fused with ``standstill_yaw_rate_variance`` (encoders that do not move are exact), and the gyro's
yaw-rate bias is estimated as the running mean of its readings (time constant ``gyro_bias_time_s``); the
estimate is taken off every IMU yaw rate, standing or driving (``gyro_bias_rad_s``).

The outputs are a pose and twist with 6x6 covariances in the
(x, y, z, roll, pitch, yaw) order of nav_msgs/Odometry, and the odom ->
base_link transform. Non-finite inputs are refused with a reason (returned
and appended to ``rejections``); the filter state is never touched by them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np
from numba import njit

from cottonsim_common.angles import wrap_angle_scalar
from cottonsim_common.validation import require_fields
from cottonsim_world.physics.wheel_odometry import OdometryEstimate

X, Y, YAW, VX, VYAW = range(5)


_wrap = njit(cache=True)(wrap_angle_scalar)   # compiled so the kernels below can call it


@dataclass(frozen=True)
class OdometryEkfConfig:
    """EKF parameters.

    frequency_hz: how often the caller runs predict (robot_localization: 50).
    process_noise_diag: per-second process noise of x, y, yaw, vx, vyaw
        (robot_localization's 2D defaults: 0.05, 0.05, 0.06, 0.025, 0.02).
    initial_covariance_diag: of the start state (robot_localization: 1e-9).
    max_dt_s: a predict longer than this is refused (clock jump) [s].
    slip_check: use the IMU's forward acceleration to detect slipping wheels (see the module doc).
    slip_speed_threshold_m_s: wheel and IMU forward speeds differing by more than this = slipping [m/s].
    slip_blend_time_s: time constant pulling the IMU speed towards the wheels' while they agree [s].
    slip_speed_variance_m2_s2: variance of the IMU forward speed fused while slipping [m^2/s^2].
    slip_yaw_rate_variance_scale: the wheels' yaw-rate variance is multiplied by this while slipping.
    gravity_m_s2: magnitude of gravity removed from the IMU's specific force [m/s^2].
    standstill_speed_m_s / standstill_yaw_rate_rad_s: the wheels stand within these [m/s], [rad/s].
    standstill_yaw_rate_variance: the variance given to the standing wheels' yaw rate [rad^2/s^2].
    gyro_bias_time_s: time constant of the gyro-bias mean taken while standing [s].
    """

    frequency_hz: float = 50.0
    process_noise_diag: Tuple[float, float, float, float, float] = (0.05, 0.05, 0.06, 0.025, 0.02)
    initial_covariance_diag: Tuple[float, float, float, float, float] = (1e-9, 1e-9, 1e-9, 1e-9, 1e-9)
    max_dt_s: float = 1.0
    slip_check: bool = True
    slip_speed_threshold_m_s: float = 0.15
    slip_blend_time_s: float = 0.5
    slip_speed_variance_m2_s2: float = 0.01
    slip_yaw_rate_variance_scale: float = 100.0
    gravity_m_s2: float = 9.8
    standstill_speed_m_s: float = 0.001
    standstill_yaw_rate_rad_s: float = 0.001
    standstill_yaw_rate_variance: float = 1e-6
    gyro_bias_time_s: float = 10.0

    def __post_init__(self) -> None:
        require_fields(self, "OdometryEkfConfig.", flags=("slip_check",),
                       positive=("frequency_hz", "max_dt_s", "slip_speed_threshold_m_s", "slip_blend_time_s",
                                 "slip_speed_variance_m2_s2", "gravity_m_s2", "standstill_speed_m_s",
                                 "standstill_yaw_rate_rad_s", "standstill_yaw_rate_variance", "gyro_bias_time_s"))
        v = self.slip_yaw_rate_variance_scale
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 1):
            raise ValueError(f"OdometryEkfConfig.slip_yaw_rate_variance_scale must be a finite number >= 1, got {v!r}")
        for name in ("process_noise_diag", "initial_covariance_diag"):
            values = getattr(self, name)
            if len(values) != 5 or not all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0
                                           for v in values):
                raise ValueError(f"OdometryEkfConfig.{name} must be 5 finite numbers > 0, got {values!r}")


_TWO_D_TINY_VARIANCE = 1e-9   # of the 3-D entries a planar filter does not observe (robot_localization's two_d_mode)


def forward_acceleration(specific_force_m_s2: Sequence[float], orientation_xyzw: Optional[Sequence[float]],
                         gravity_m_s2: float = 9.8) -> float:
    """Forward (body x) acceleration [m/s^2] from an IMU's specific force (body axes, gravity included) and
    its attitude quaternion (body -> world, x y z w): a_x = f_x - g R[2][0] (R[2][0] = 2 (x z - w y)).
    No attitude = a level robot. Raises ValueError on non-finite or malformed input."""
    try:
        f = _floats(specific_force_m_s2)
        q = [0.0, 0.0, 0.0, 1.0] if orientation_xyzw is None else _floats(orientation_xyzw)
    except (TypeError, ValueError):
        raise ValueError("accel_body_m_s2 / orientation_xyzw must be numbers") from None
    if len(f) != 3 or len(q) != 4 or not all(map(math.isfinite, f + q)):
        raise ValueError(f"accel_body_m_s2 must be 3 and orientation_xyzw 4 finite numbers, got {f!r}, {q!r}")
    qx, qy, qz, qw = q
    n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if n < 1e-9:
        raise ValueError("orientation_xyzw is a zero quaternion")
    x, y, z, w = qx / n, qy / n, qz / n, qw / n
    return f[0] - gravity_m_s2 * 2.0 * (x * z - w * y)


def _floats(values) -> List[float]:
    """values as a list of Python floats; a 1-D float64 array (the IMU's, at 50 Hz) by one tolist()."""
    if isinstance(values, np.ndarray) and values.ndim == 1 and values.dtype == np.float64:
        return values.tolist()
    return [float(v) for v in values]


# The filter's arithmetic, compiled. At 50 Hz on 5-vectors and 5x5 matrices the interpreter's cost per
# float operation (~40 instructions per bytecode here, a boxed float per result) dominated the odometry
# and IMU updates (~0.35 M instructions per predict + two updates + output as Python lists). Each kernel
# below spells out the same operations, in the same order, as the former list code, so the results are
# bit-identical (test_odometry_ekf.py replays a reference); numba without fastmath neither reorders nor
# fuses floating-point operations.

@njit(cache=True)
def _predict_kernel(s, p, cos_yaw, sin_yaw, dt, q_diag):  # pragma: no cover
    """Constant-velocity motion over dt [s] in place: s (5,), P' = F P F^T + Q dt with F the motion Jacobian.

    cos_yaw / sin_yaw: of the yaw before the step (taken by the caller with Python's math, as before).
    F = I except F[X,YAW], F[X,VX], F[Y,YAW], F[Y,VX], F[YAW,VYAW].
    """
    vx = s[VX]
    f_x_yaw, f_x_vx = -vx * sin_yaw * dt, cos_yaw * dt
    f_y_yaw, f_y_vx = vx * cos_yaw * dt, sin_yaw * dt
    s[X] += vx * cos_yaw * dt
    s[Y] += vx * sin_yaw * dt
    s[YAW] = _wrap(s[YAW] + s[VYAW] * dt)
    fp = np.empty((5, 5))
    for j in range(5):               # F times column j of P
        fp[X, j] = p[X, j] + f_x_yaw * p[YAW, j] + f_x_vx * p[VX, j]
        fp[Y, j] = p[Y, j] + f_y_yaw * p[YAW, j] + f_y_vx * p[VX, j]
        fp[YAW, j] = p[YAW, j] + dt * p[VYAW, j]
        fp[VX, j] = p[VX, j]
        fp[VYAW, j] = p[VYAW, j]
    for i in range(5):               # row i of F P, times F^T
        p[i, X] = fp[i, X] + f_x_yaw * fp[i, YAW] + f_x_vx * fp[i, VX]
        p[i, Y] = fp[i, Y] + f_y_yaw * fp[i, YAW] + f_y_vx * fp[i, VX]
        p[i, YAW] = fp[i, YAW] + dt * fp[i, VYAW]
        p[i, VX] = fp[i, VX]
        p[i, VYAW] = fp[i, VYAW]
        p[i, i] += q_diag[i] * dt


@njit(cache=True)
def _update_one_kernel(s, p, row, z, r):  # pragma: no cover
    """Kalman update in place with H picking state ``row``, measurement z, variance r (Joseph form)."""
    innovation = z - s[row]
    if row == YAW:
        innovation = _wrap(innovation)
    col0 = p[:, row].copy()                  # P H^T
    hp0 = p[row, :].copy()                   # H P
    k0 = np.empty(5)
    for i in range(5):
        k0[i] = col0[i] / (col0[row] + r)
    for i in range(5):
        s[i] += k0[i] * innovation
    # Joseph form P' = (I - K H) P (I - K H)^T + K R K^T keeps P symmetric positive definite;
    # with H P = row r0 of P: A = P - k0 p[r0], then P' = A - A[:, r0] k0^T + r k0 k0^T.
    a = np.empty((5, 5))
    for i in range(5):
        for j in range(5):
            a[i, j] = p[i, j] - k0[i] * hp0[j]
    for i in range(5):
        for j in range(5):
            p[i, j] = a[i, j] - a[i, row] * k0[j] + k0[i] * r * k0[j]
    s[YAW] = _wrap(s[YAW])


@njit(cache=True)
def _update_two_kernel(s, p, r0, r1, z0, z1, q0, q1):  # pragma: no cover
    """Kalman update in place with H picking state rows r0 and r1, measurements z0, z1, R = diag(q0, q1)."""
    innovation0 = z0 - s[r0]
    innovation1 = z1 - s[r1]
    if r0 == YAW:
        innovation0 = _wrap(innovation0)
    if r1 == YAW:
        innovation1 = _wrap(innovation1)
    col0 = p[:, r0].copy()                   # P H^T, two columns
    col1 = p[:, r1].copy()
    hp0 = p[r0, :].copy()                    # H P, two rows
    hp1 = p[r1, :].copy()
    a, b = col0[r0] + q0, col1[r0]           # S = H P H^T + R
    c, d = col0[r1], col1[r1] + q1
    det = a * d - b * c
    ia, ib, ic, id_ = d / det, -b / det, -c / det, a / det      # S^-1
    k0 = np.empty(5)                         # K = P H^T S^-1, its two columns
    k1 = np.empty(5)
    for i in range(5):
        k0[i] = col0[i] * ia + col1[i] * ic
        k1[i] = col0[i] * ib + col1[i] * id_
    for i in range(5):
        s[i] += k0[i] * innovation0 + k1[i] * innovation1
    am = np.empty((5, 5))
    for i in range(5):
        for j in range(5):
            am[i, j] = p[i, j] - k0[i] * hp0[j] - k1[i] * hp1[j]
    for i in range(5):
        for j in range(5):
            p[i, j] = (am[i, j] - am[i, r0] * k0[j] - am[i, r1] * k1[j] + k0[i] * q0 * k0[j]
                       + k1[i] * q1 * k1[j])
    s[YAW] = _wrap(s[YAW])


@njit(cache=True)
def _covariances_6x6(p, tiny):  # pragma: no cover
    """/odometry/filtered's pose and twist covariances, 6x6 in (x, y, z, roll, pitch, yaw), from the 5x5 P.

    Pose: x, y, yaw of P; twist: vx and vyaw of P (at vx and yaw rate). The entries a planar filter does
    not observe get ``tiny`` on the diagonal (two_d_mode): z, roll, pitch; vy, vz, roll and pitch rates.
    """
    pose = np.zeros((6, 6))
    twist = np.zeros((6, 6))
    for i in (2, 3, 4):
        pose[i, i] = tiny
    for i in (1, 2, 3, 4):
        twist[i, i] = tiny
    pose_cells = (0, 1, 5)
    pose_states = (X, Y, YAW)
    for a in range(3):
        for b in range(3):
            pose[pose_cells[a], pose_cells[b]] = p[pose_states[a], pose_states[b]]
    twist_cells = (0, 5)
    twist_states = (VX, VYAW)
    for a in range(2):
        for b in range(2):
            twist[twist_cells[a], twist_cells[b]] = p[twist_states[a], twist_states[b]]
    return pose, twist


class OdometryEkf:
    """5-state planar EKF: predict(dt), update_wheel_odometry, update_imu.

    The simulator runs it at 50 Hz on 5-vectors and 5x5 matrices, where
    numpy spends more time dispatching than computing and the interpreter
    more than both; the filter therefore keeps its state and covariance in
    numpy arrays that compiled kernels update in place, writing out the
    products with the structure of the model (the Jacobian differs from the
    identity in five entries; every measurement picks state entries). The
    checks of the inputs stay in Python. ``state`` and ``covariance``
    return numpy copies.
    """

    def __init__(self, config: OdometryEkfConfig = OdometryEkfConfig()):
        self.config = config
        self._q_diag = np.array([float(v) for v in config.process_noise_diag])
        self.rejections: List[str] = []
        self.reset()

    def reset(self, x_m: float = 0.0, y_m: float = 0.0, yaw_rad: float = 0.0) -> None:
        self._s = np.array([float(x_m), float(y_m), _wrap(float(yaw_rad)), 0.0, 0.0])
        self._p = np.diag([float(v) for v in self.config.initial_covariance_diag])
        self._accel_x: Optional[float] = None      # latest IMU forward acceleration (gravity removed) [m/s^2]
        self._v_imu = 0.0                           # IMU-integrated forward speed [m/s]
        self._last_dt = 0.0
        self.slipping = False
        self.slip_events = 0                        # times slipping started
        self.standing = False                       # the wheels stand (the last wheel odometry)
        self.gyro_bias_rad_s = 0.0                  # the gyro's yaw-rate bias, estimated while standing

    @property
    def imu_speed_m_s(self) -> float:
        """The IMU-integrated forward speed the slip check compares the wheels with [m/s]."""
        return self._v_imu

    @property
    def state(self) -> np.ndarray:
        """[x, y, yaw, vx, vyaw] (a copy)."""
        return self._s.copy()

    @property
    def covariance(self) -> np.ndarray:
        """5x5 covariance of ``state`` (a copy)."""
        return self._p.copy()

    def _reject(self, reason: str) -> str:
        self.rejections.append(reason)
        return reason

    @staticmethod
    def _bad_number(name: str, value) -> Optional[str]:
        try:
            ok = math.isfinite(float(value))
        except (TypeError, ValueError):
            return f"{name} is not a number ({value!r})"
        return None if ok else f"{name} contains NaN or inf ({value!r})"

    # ------------------------------------------------------------- predict
    def predict(self, dt_s: float) -> Optional[str]:
        """Propagate the state by dt_s [s]; returns None or the reason it was refused."""
        try:
            dt = float(dt_s)
        except (TypeError, ValueError):
            return self._reject(f"predict: dt_s is not a number ({dt_s!r})")
        if not math.isfinite(dt) or dt < 0 or dt > self.config.max_dt_s:
            return self._reject(f"predict: dt_s must be finite and in [0, {self.config.max_dt_s}] s, got {dt_s!r}")
        yaw = self._s.item(YAW)
        _predict_kernel(self._s, self._p, math.cos(yaw), math.sin(yaw), dt, self._q_diag)
        if self._accel_x is not None:
            self._v_imu += self._accel_x * dt
        self._last_dt = dt
        return None

    # ------------------------------------------------------------- updates
    def _update(self, rows: Sequence[int], z: Sequence[float], r_diag: Sequence[float]) -> None:
        """Kalman update with H picking ``rows`` (one or two) of the state; R = diag(r_diag)."""
        if len(rows) == 1:
            _update_one_kernel(self._s, self._p, rows[0], float(z[0]), float(r_diag[0]))
        else:
            _update_two_kernel(self._s, self._p, rows[0], rows[1], float(z[0]), float(z[1]), float(r_diag[0]),
                               float(r_diag[1]))

    @staticmethod
    def _variance(cov, name: str) -> Tuple[Optional[float], Optional[str]]:
        try:
            v = float(cov)
        except (TypeError, ValueError):
            return None, f"{name} must be a number, got {cov!r}"
        if not math.isfinite(v) or v <= 0:
            return None, f"{name} must be a finite variance > 0, got {cov!r}"
        return v, None

    def update_wheel_odometry(self, v_m_s: float, w_rad_s: float, cov: Sequence[float]) -> Optional[str]:
        """Fuse wheel odometry forward speed v [m/s] and yaw rate w [rad/s].

        cov: variances (var_v, var_w), or the 6x6 / 36-element twist
        covariance of nav_msgs/Odometry (entries [0,0] and [5,5] are used).
        """
        bad = self._bad_number("v_m_s", v_m_s) or self._bad_number("w_rad_s", w_rad_s)
        if bad:
            return self._reject(f"wheel odometry rejected: {bad}")
        if isinstance(cov, (tuple, list)) and len(cov) == 2:
            pair = cov
        else:
            try:
                arr = np.asarray(cov, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                return self._reject(f"wheel odometry rejected: cov must be numbers, got {cov!r}")
            pair = (arr[0], arr[35]) if arr.size == 36 else arr
            if len(pair) != 2:
                return self._reject(f"wheel odometry rejected: cov must be (var_v, var_w) or 6x6, got {arr.size} values")
        var_v, err_v = self._variance(pair[0], "wheel odometry var_v")
        var_w, err_w = self._variance(pair[1], "wheel odometry var_w")
        if err_v or err_w:
            return self._reject(f"wheel odometry rejected: {err_v or err_w}")
        v = float(v_m_s)
        if self.config.slip_check and self._accel_x is not None:
            c = self.config
            diff = v - self._v_imu
            if not self.slipping and abs(diff) > c.slip_speed_threshold_m_s:
                self.slipping = True
                self.slip_events += 1
            elif self.slipping and abs(diff) < 0.5 * c.slip_speed_threshold_m_s:
                self.slipping = False
            if self.slipping:        # the IMU's speed instead of the spinning wheels'
                # a slipping robot moves no faster than its wheels turn and not against them: this bounds
                # the IMU speed's drift (accelerometer bias, the IMU's lever arm while turning), and once
                # the wheels stop the slip is over
                self._v_imu = min(max(self._v_imu, min(0.0, v)), max(0.0, v))
                if abs(v - self._v_imu) < 0.5 * c.slip_speed_threshold_m_s:
                    self.slipping = False
            if self.slipping:
                self._update((VX, VYAW), (self._v_imu, float(w_rad_s)),
                             (c.slip_speed_variance_m2_s2, var_w * c.slip_yaw_rate_variance_scale))
                return None
            self._v_imu += diff * min(1.0, self._last_dt / c.slip_blend_time_s)
        c = self.config
        self.standing = abs(v) <= c.standstill_speed_m_s and abs(float(w_rad_s)) <= c.standstill_yaw_rate_rad_s
        if self.standing:
            var_w = min(var_w, c.standstill_yaw_rate_variance)
        self._update((VX, VYAW), (v, float(w_rad_s)), (var_v, var_w))
        return None

    def update_imu(self, yaw_rate_rad_s: float, cov: float, yaw: Optional[float] = None,
                   yaw_cov: Optional[float] = None, accel_body_m_s2: Optional[Sequence[float]] = None,
                   orientation_xyzw: Optional[Sequence[float]] = None) -> Optional[str]:
        """Fuse the IMU yaw rate [rad/s] (variance cov) and optionally its yaw [rad].

        yaw_cov: variance of yaw [rad^2]; required when yaw is given.
        accel_body_m_s2 (with orientation_xyzw, the IMU's attitude in base_link axes): the specific force
        [m/s^2] (gravity included, as sensor_msgs/Imu); its forward part feeds the slip check.
        """
        bad = self._bad_number("yaw_rate_rad_s", yaw_rate_rad_s) or (
            self._bad_number("yaw", yaw) if yaw is not None else None)
        if bad:
            return self._reject(f"IMU rejected: {bad}")
        if accel_body_m_s2 is not None and self.config.slip_check:
            try:
                ax = forward_acceleration(accel_body_m_s2, orientation_xyzw, self.config.gravity_m_s2)
            except ValueError as exc:
                return self._reject(f"IMU rejected: {exc}")
            self._accel_x = ax
        var_r, err = self._variance(cov, "IMU yaw-rate cov")
        if err:
            return self._reject(f"IMU rejected: {err}")
        rate = float(yaw_rate_rad_s)
        if self.standing:
            weight = min(1.0, 1.0 / (self.config.gyro_bias_time_s * self.config.frequency_hz))
            self.gyro_bias_rad_s += (rate - self.gyro_bias_rad_s) * weight
        rate -= self.gyro_bias_rad_s
        if yaw is None:
            self._update((VYAW,), (rate,), (var_r,))
            return None
        var_y, err = self._variance(yaw_cov, "IMU yaw_cov")
        if err:
            return self._reject(f"IMU rejected: {err}")
        self._update((YAW, VYAW), (float(yaw), rate), (var_y, var_r))
        return None

    # -------------------------------------------------------------- output
    def output(self) -> OdometryEstimate:
        """Current estimate as /odometry/filtered contents."""
        pose, twist = _covariances_6x6(self._p, _TWO_D_TINY_VARIANCE)
        x, y, yaw, vx, vyaw = self._s.tolist()
        return OdometryEstimate(x, y, yaw, vx, vyaw, pose, twist)
