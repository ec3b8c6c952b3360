"""UR5e kinematics: DH table, forward kinematics and closed-form inverse kinematics.

Both the simulator (cottonsim_world.robot.ur5e) and the robot-side arm code
(cottonsim_manipulation) use this module, so the two can never disagree about
where the tool is.

The UR5e's standard Denavit-Hartenberg table (Universal Robots' published
parameters, the same as ROS-Industrial's ur_description; lengths in metres):

    i   a_i        alpha_i   d_i
    1   0          +pi/2     d1 = 0.1625
    2   a2=-0.425   0        0
    3   a3=-0.3922  0        0
    4   0          +pi/2     d4 = 0.1333
    5   0          -pi/2     d5 = 0.0997
    6   0           0        d6 = 0.0996

A_i = Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i); T_base_tool0 = A_1 ... A_6. The base
frame is the UR controller's 'base' (ur5e_base in the URDF: ur5e_base_link
turned by pi about z); tool0 (DH frame 6) has z out of the flange.

Inverse kinematics is the analytic solution of UR arms (joints 2-4 parallel,
wrist axes 5 and 6 intersecting the plane of 2-4 at fixed offsets):

* q1 from the wrist point p05 = p - d6 z6, which lies d4 from the vertical
  plane of the arm: r sin(q1 - psi) = d4, two solutions (shoulder sign s);
  none when r < d4 (the pose is inside the cylinder round the base axis);
* q5 from the orientation: the shoulder axis n1 = (sin q1, -cos q1, 0) seen in
  the tool frame is (sin q5 cos q6, -sin q5 sin q6, cos q5), so
  q5 = w * atan2(|(v_x, v_y)|, v_z) (wrist sign w) and q6 = atan2(-w v_y, w v_x);
* q2, q3, q4 from the planar 2R arm of the parallel joints (elbow sign e).

So up to 8 solutions (s, w, e). Singularities give a consistent answer, never
NaN: at the wrist singularity (sin q5 ~ 0, axes 4 and 6 aligned) q6 keeps the
reference value (the current joint) and q4 takes the whole rotation; at the
shoulder singularity (r = d4) and the elbow's stretched/folded limits the
solution is taken on the workspace edge; the result names the singularity.
Every joint is then moved by whole turns to the representation inside its
limits nearest the reference joints; solutions outside the limits are dropped,
the rest sorted by (weighted) distance to the reference.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Sequence, Tuple

import numpy as np

JOINT_NAMES: Tuple[str, ...] = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
NUM_JOINTS = len(JOINT_NAMES)
TWO_PI = 2.0 * math.pi

# Position limits of the published UR5e model (ur_description joint_limits.yaml) [rad]:
# +-2 pi for every joint except the elbow, +-pi (its cables and the forearm folding
# onto the upper arm). Speed limit 180 deg/s for every joint of the e-Series UR5e.
UR5E_LOWER_LIMITS_RAD: Tuple[float, ...] = (-TWO_PI, -TWO_PI, -math.pi, -TWO_PI, -TWO_PI, -TWO_PI)
UR5E_UPPER_LIMITS_RAD: Tuple[float, ...] = (TWO_PI, TWO_PI, math.pi, TWO_PI, TWO_PI, TWO_PI)
UR5E_MAX_SPEED_RAD_S: Tuple[float, ...] = (math.pi,) * NUM_JOINTS

# Branch signs of the 8 solutions, in the order inverse_kinematics() labels them:
# (shoulder s, wrist w, elbow e); w = sign of sin(q5), e = sign of sin(q3).
BRANCHES: Tuple[Tuple[int, int, int], ...] = tuple(
    (s, w, e) for s in (1, -1) for w in (1, -1) for e in (1, -1)
)


@dataclass(frozen=True)
class Ur5eKinematics:
    """UR5e DH lengths [m] (defaults: Universal Robots' published values)."""

    d1_m: float = 0.1625
    a2_m: float = -0.425
    a3_m: float = -0.3922
    d4_m: float = 0.1333
    d5_m: float = 0.0997
    d6_m: float = 0.0996

    def __post_init__(self) -> None:
        for name in ("d1_m", "a2_m", "a3_m", "d4_m", "d5_m", "d6_m"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"Ur5eKinematics.{name} must be a finite number, got {value!r}")
            if abs(value) > 5.0:
                raise ValueError(f"Ur5eKinematics.{name} = {value} m is not a plausible UR5e length")
        if self.a2_m == 0.0 or self.a3_m == 0.0:
            raise ValueError("Ur5eKinematics.a2_m and a3_m must be non-zero (the upper arm and forearm)")

    def dh_table(self) -> Tuple[Tuple[float, float, float], ...]:
        """Rows (a_i [m], alpha_i [rad], d_i [m]) for i = 1..6."""
        half_pi = math.pi / 2.0
        return (
            (0.0, half_pi, self.d1_m),
            (self.a2_m, 0.0, 0.0),
            (self.a3_m, 0.0, 0.0),
            (0.0, half_pi, self.d4_m),
            (0.0, -half_pi, self.d5_m),
            (0.0, 0.0, self.d6_m),
        )

    @property
    def max_reach_m(self) -> float:
        """Farthest the flange gets from the shoulder point (0, 0, d1) [m]."""
        return abs(self.a2_m) + abs(self.a3_m) + math.hypot(self.d4_m + self.d6_m, self.d5_m)


DEFAULT_KINEMATICS = Ur5eKinematics()


def dh_transform(a_m: float, alpha_rad: float, d_m: float, theta_rad: float) -> np.ndarray:
    """Standard DH step Rz(theta) Tz(d) Tx(a) Rx(alpha) as a 4x4 matrix."""
    ct, st = math.cos(theta_rad), math.sin(theta_rad)
    ca, sa = math.cos(alpha_rad), math.sin(alpha_rad)
    return np.array(
        [
            [ct, -st * ca, st * sa, a_m * ct],
            [st, ct * ca, -ct * sa, a_m * st],
            [0.0, sa, ca, d_m],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def dh_transforms(a_m: float, alpha_rad: float, d_m: float, theta_rad: np.ndarray) -> np.ndarray:
    """dh_transform for an array of angles: shape theta.shape + (4, 4)."""
    theta = np.asarray(theta_rad, dtype=float)
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = math.cos(alpha_rad), math.sin(alpha_rad)
    out = np.zeros(theta.shape + (4, 4))
    out[..., 0, 0] = ct
    out[..., 0, 1] = -st * ca
    out[..., 0, 2] = st * sa
    out[..., 0, 3] = a_m * ct
    out[..., 1, 0] = st
    out[..., 1, 1] = ct * ca
    out[..., 1, 2] = -ct * sa
    out[..., 1, 3] = a_m * st
    out[..., 2, 1] = sa
    out[..., 2, 2] = ca
    out[..., 2, 3] = d_m
    out[..., 3, 3] = 1.0
    return out


def _rigid_inverse(t: np.ndarray) -> np.ndarray:
    """Inverse of rigid 4x4 transforms (any leading shape)."""
    out = np.zeros_like(t)
    rt = np.swapaxes(t[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rt, t[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def joint_vector(values: Sequence[float], what: str) -> np.ndarray:
    """Six finite joint values as a float array; ValueError naming `what` otherwise."""
    try:
        arr = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be {NUM_JOINTS} numbers, got {values!r}") from None
    if arr.shape != (NUM_JOINTS,):
        raise ValueError(f"{what} must have {NUM_JOINTS} values, got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} contains NaN or infinity: {arr.tolist()}")
    return arr


def forward_kinematics(q_rad: Sequence[float], kinematics: Optional[Ur5eKinematics] = None) -> np.ndarray:
    """4x4 pose of tool0 (DH frame 6, z out of the flange) in the arm's base frame for joints q [rad]."""
    q = joint_vector(q_rad, "joint angles")
    kin = kinematics or DEFAULT_KINEMATICS
    out = np.eye(4)
    for (a, alpha, d), theta in zip(kin.dh_table(), q):
        out = out @ dh_transform(a, alpha, d, theta)
    return out


def link_frames(q_rad: np.ndarray, kinematics: Optional[Ur5eKinematics] = None) -> np.ndarray:
    """Poses of the DH frames 0 (base) .. 6 (tool0) in the base frame.

    q_rad: (6,) or (K, 6) joint angles [rad]; returns (7, 4, 4) or (K, 7, 4, 4).
    Frame i (i >= 1) sits on the axis of joint i + 1 (frame 6: the flange).
    """
    q = np.asarray(q_rad, dtype=float)
    single = q.ndim == 1
    q = np.atleast_2d(q)
    if q.ndim != 2 or q.shape[1] != NUM_JOINTS:
        raise ValueError(f"joint angles must have shape (6,) or (K, 6), got {np.shape(q_rad)}")
    if not np.all(np.isfinite(q)):
        raise ValueError("joint angles contain NaN or infinity")
    kin = kinematics or DEFAULT_KINEMATICS
    frames = np.empty((q.shape[0], NUM_JOINTS + 1, 4, 4))
    frames[:, 0] = np.eye(4)
    for i, (a, alpha, d) in enumerate(kin.dh_table()):
        frames[:, i + 1] = frames[:, i] @ dh_transforms(a, alpha, d, q[:, i])
    return frames[0] if single else frames


# ----------------------------------------------------------------------------- inverse kinematics
@dataclass(frozen=True)
class IkConfig:
    """Limits and tolerances of inverse_kinematics().

    lower_limits_rad, upper_limits_rad: joint position limits [rad] (UR5e defaults).
    joint_weights: weights of the distance to the reference joints used to sort
        solutions, sqrt(sum w_i dq_i^2) [rad] (all 1: plain joint-space distance).
    wrist_singular_sin: |sin q5| below this is the wrist singularity: q5 is set
        to 0 or pi exactly, q6 keeps its reference value (the orientation error
        this adds is below this value, in rad).
    reach_tol_m: a pose up to this far outside the workspace (inside the base
        cylinder r < d4, beyond the stretched or folded elbow) is solved on the
        workspace edge and reported singular; further out it is unreachable [m].
    """

    lower_limits_rad: Tuple[float, ...] = UR5E_LOWER_LIMITS_RAD
    upper_limits_rad: Tuple[float, ...] = UR5E_UPPER_LIMITS_RAD
    joint_weights: Tuple[float, ...] = (1.0,) * NUM_JOINTS
    wrist_singular_sin: float = 1e-7
    reach_tol_m: float = 1e-7

    def __post_init__(self) -> None:
        for name in ("lower_limits_rad", "upper_limits_rad", "joint_weights"):
            values = getattr(self, name)
            if len(values) != NUM_JOINTS or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values
            ):
                raise ValueError(f"IkConfig.{name} must be {NUM_JOINTS} finite numbers, got {values!r}")
        for name, lo, hi in zip(JOINT_NAMES, self.lower_limits_rad, self.upper_limits_rad):
            if lo >= hi:
                raise ValueError(f"IkConfig limits of {name}: lower {lo} must be below upper {hi}")
        if any(w <= 0 for w in self.joint_weights):
            raise ValueError(f"IkConfig.joint_weights must all be > 0, got {self.joint_weights}")
        for name in ("wrist_singular_sin", "reach_tol_m"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not (0.0 <= value < 1e-2):
                raise ValueError(f"IkConfig.{name} must be in [0, 0.01), got {value!r}")


DEFAULT_IK_CONFIG = IkConfig()


@dataclass(frozen=True)
class IkResult:
    """The solutions of one inverse-kinematics query.

    solutions: (k, 6) joint angles [rad] inside the limits, nearest the reference first.
    branches: the (shoulder, wrist, elbow) signs of each solution (see BRANCHES).
    distances: weighted joint-space distance of each solution to the reference [rad].
    status: 'ok' (k >= 1), 'unreachable' (no arm configuration has this pose) or
        'out_of_limits' (configurations exist, none inside the joint limits).
    singular: the singularities the pose is at: a subset of ('shoulder', 'elbow', 'wrist').
    """

    solutions: np.ndarray
    branches: Tuple[Tuple[int, int, int], ...]
    distances: np.ndarray
    status: str
    singular: Tuple[str, ...] = field(default=())

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def best(self) -> Optional[np.ndarray]:
        """The solution nearest the reference, or None."""
        return self.solutions[0].copy() if len(self.solutions) else None


def _check_poses(pose: np.ndarray) -> np.ndarray:
    t = np.asarray(pose, dtype=float)
    if t.shape[-2:] != (4, 4):
        raise ValueError(f"a pose must be a 4x4 homogeneous matrix, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("the pose contains NaN or infinity")
    r = t[..., :3, :3]
    err = np.abs(np.einsum("...ji,...jk->...ik", r, r) - np.eye(3)).max() if r.size else 0.0
    if err > 1e-6:
        raise ValueError(f"the pose's rotation is not orthonormal (max |R^T R - I| = {err:.2e})")
    return t


def ik_branches(
    poses: np.ndarray,
    q6_reference_rad: np.ndarray,
    kinematics: Optional[Ur5eKinematics] = None,
    config: Optional[IkConfig] = None,
) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All 8 analytic branches of N poses, angles wrapped to (-pi, pi], no joint limits.

    poses: (N, 4, 4) tool0 poses in the base frame; q6_reference_rad: (N,) the q6
    used at the wrist singularity. Returns q (N, 8, 6) in BRANCHES order (NaN
    where a branch does not exist), valid (N, 8) and singular flags (N, 3) for
    (shoulder, elbow, wrist).
    """
    kin = kinematics or DEFAULT_KINEMATICS
    cfg = config or DEFAULT_IK_CONFIG
    t = np.asarray(poses, dtype=float)
    n = t.shape[0]
    d1, a2, a3, d4, d5, d6 = kin.d1_m, kin.a2_m, kin.a3_m, kin.d4_m, kin.d5_m, kin.d6_m
    rot = t[:, :3, :3]
    p05 = t[:, :3, 3] - d6 * rot[:, :, 2]

    # q1: r sin(q1 - psi) = d4 (shoulder sign s: +acos / -acos).
    r = np.hypot(p05[:, 0], p05[:, 1])
    psi = np.arctan2(p05[:, 1], p05[:, 0])
    shoulder_ok = r >= abs(d4) - cfg.reach_tol_m
    shoulder_singular = np.abs(r - abs(d4)) <= cfg.reach_tol_m
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(r > 0.0, d4 / np.where(r > 0.0, r, 1.0), 2.0)
    phi = np.arccos(np.minimum(np.maximum(ratio, -1.0), 1.0))
    signs = np.array([1.0, -1.0])
    q1 = psi[:, None] + signs[None, :] * phi[:, None] + 0.5 * math.pi            # (N, 2)

    # q5, q6 from n1 = (sin q1, -cos q1, 0) in the tool frame: v = R^T n1.
    n1 = np.stack([np.sin(q1), -np.cos(q1), np.zeros_like(q1)], axis=-1)     # (N, 2, 3)
    v = np.einsum("nki,nsk->nsi", rot, n1)                                     # (N, 2, 3)
    s5_abs = np.hypot(v[..., 0], v[..., 1])                                    # (N, 2)
    wrist_singular = s5_abs < cfg.wrist_singular_sin
    q5_up = np.where(wrist_singular, np.where(v[..., 2] >= 0.0, 0.0, math.pi), np.arctan2(s5_abs, v[..., 2]))
    q5 = q5_up[..., None] * signs                                              # (N, 2, 2)
    q6_free = np.arctan2(-signs * v[..., 1:2], signs * v[..., 0:1])            # (N, 2, 2)
    q6_ref = np.broadcast_to(np.asarray(q6_reference_rad, dtype=float).reshape(n, 1, 1), q6_free.shape)
    q6 = np.where(wrist_singular[..., None], q6_ref, q6_free)
    q1b = np.broadcast_to(q1[..., None], q5.shape)

    # T14 = A1^-1 T06 A6^-1 A5^-1: the planar part of joints 2-4.
    a1_inv = _rigid_inverse(dh_transforms(0.0, math.pi / 2.0, d1, q1b))
    a5_inv = _rigid_inverse(dh_transforms(0.0, -math.pi / 2.0, d5, q5))
    a6_inv = _rigid_inverse(dh_transforms(0.0, 0.0, d6, q6))
    t14 = a1_inv @ t[:, None, None] @ a6_inv @ a5_inv                           # (N, 2, 2, 4, 4)
    q234 = np.arctan2(t14[..., 1, 0], t14[..., 0, 0])
    x, y = t14[..., 0, 3], t14[..., 1, 3]
    reach_sq = x * x + y * y
    c3 = (reach_sq - a2 * a2 - a3 * a3) / (2.0 * a2 * a3)
    c3_tol = cfg.reach_tol_m * (np.sqrt(reach_sq) + cfg.reach_tol_m) / abs(a2 * a3)
    elbow_ok = np.abs(c3) <= 1.0 + c3_tol
    elbow_singular = np.abs(c3) >= 1.0 - c3_tol
    q3_up = np.arccos(np.minimum(np.maximum(c3, -1.0), 1.0))
    q3 = q3_up[..., None] * signs                                              # (N, 2, 2, 2)
    q2 = np.arctan2(y, x)[..., None] - np.arctan2(a3 * np.sin(q3), a2 + a3 * np.cos(q3))
    q4 = q234[..., None] - q2 - q3

    q = np.stack(
        [
            np.broadcast_to(q1b[..., None], q3.shape),
            q2,
            q3,
            q4,
            np.broadcast_to(q5[..., None], q3.shape),
            np.broadcast_to(q6[..., None], q3.shape),
        ],
        axis=-1,
    ).reshape(n, 8, NUM_JOINTS)
    q = np.mod(q + math.pi, TWO_PI) - math.pi
    q = np.where(q <= -math.pi, q + TWO_PI, q)
    valid = (shoulder_ok[:, None, None, None] & np.broadcast_to(elbow_ok[..., None], q3.shape)).reshape(n, 8)
    q[~valid] = np.nan
    singular = np.stack(
        [
            shoulder_singular,
            np.any((elbow_singular & elbow_ok).reshape(n, -1), axis=1),
            np.any(wrist_singular, axis=1) & shoulder_ok,
        ],
        axis=-1,
    )
    return q, valid, singular


_TURNS_RAD = TWO_PI * np.array([0.0, -1.0, 1.0, -2.0, 2.0, -3.0, 3.0])


def wrap_into_limits(
    q_rad: np.ndarray, reference_rad: np.ndarray, lower_rad: np.ndarray, upper_rad: np.ndarray
) -> np.ndarray:
    """Move each angle by whole turns to the value inside [lower, upper] nearest the reference.

    q_rad (..., 6); reference_rad broadcastable to it. NaN where no turn puts the
    angle inside its limits (or where q is NaN).
    """
    q = np.asarray(q_rad, dtype=float)
    ref = np.broadcast_to(np.asarray(reference_rad, dtype=float), q.shape)
    eps = 1e-12
    base = q + TWO_PI * np.round((ref - q) / TWO_PI)                          # nearest the reference
    cand = base[..., None] + _TURNS_RAD                                        # (..., 6, 7)
    lo = np.asarray(lower_rad, dtype=float)[..., None]
    hi = np.asarray(upper_rad, dtype=float)[..., None]
    dist = np.where((cand >= lo - eps) & (cand <= hi + eps), np.abs(cand - ref[..., None]), np.inf)
    pick = np.argmin(dist, axis=-1)
    best = np.take_along_axis(cand, pick[..., None], axis=-1)[..., 0]
    found = np.take_along_axis(dist, pick[..., None], axis=-1)[..., 0] < np.inf
    return np.where(found, np.minimum(np.maximum(best, lo[..., 0]), hi[..., 0]), np.nan)


def inverse_kinematics(
    pose: np.ndarray,
    reference_rad: Optional[Sequence[float]] = None,
    kinematics: Optional[Ur5eKinematics] = None,
    config: Optional[IkConfig] = None,
) -> IkResult:
    """Every joint solution (inside the limits) that puts tool0 at `pose`.

    pose: 4x4 pose of tool0 in the base frame (DH frame 6). reference_rad: the
    current joints (default all zero): each solution takes the turn of each
    joint nearest it, solutions are sorted by distance to it, and at the wrist
    singularity q6 keeps its value. ValueError on a malformed pose or reference.
    """
    cfg = config or DEFAULT_IK_CONFIG
    t = _check_poses(pose)
    if t.shape != (4, 4):
        raise ValueError(f"inverse_kinematics takes one 4x4 pose, got shape {t.shape}")
    ref = np.zeros(NUM_JOINTS) if reference_rad is None else joint_vector(reference_rad, "reference joints")
    q, valid, singular = ik_branches(t[None], ref[5:6], kinematics, cfg)
    names = tuple(name for name, flag in zip(("shoulder", "elbow", "wrist"), singular[0]) if flag)
    if not valid[0].any():
        return IkResult(np.zeros((0, NUM_JOINTS)), (), np.zeros(0), "unreachable", names)
    lower = np.asarray(cfg.lower_limits_rad)
    upper = np.asarray(cfg.upper_limits_rad)
    wrapped = wrap_into_limits(q[0], ref, lower, upper)
    inside = np.all(np.isfinite(wrapped), axis=1)
    if not inside.any():
        return IkResult(np.zeros((0, NUM_JOINTS)), (), np.zeros(0), "out_of_limits", names)
    weights = np.asarray(cfg.joint_weights)
    idx = np.flatnonzero(inside)
    dist = np.sqrt(((wrapped[idx] - ref) ** 2 * weights).sum(axis=1))
    order = idx[np.argsort(dist, kind="stable")]
    cand = wrapped[order]
    # Singular poses give coincident branches: keep the first of each group.
    same = np.abs(cand[:, None, :] - cand[None, :, :]).max(axis=2) <= 1e-9
    kept = order[~np.any(np.tril(same, k=-1), axis=1)]
    sols = wrapped[kept]
    dist = np.sqrt(((sols - ref) ** 2 * weights).sum(axis=1))
    return IkResult(sols, tuple(BRANCHES[i] for i in kept), dist, "ok", names)


def branch_of(q_rad: Sequence[float], kinematics: Optional[Ur5eKinematics] = None) -> Tuple[int, int, int]:
    """The (shoulder, wrist, elbow) signs of a configuration, as BRANCHES labels them.

    Wrist: sign of sin q5; elbow: sign of sin q3; shoulder: the sign of the
    wrist point's offset along the arm's plane (the +acos / -acos choice of q1).
    """
    q = joint_vector(q_rad, "joint angles")
    kin = kinematics or DEFAULT_KINEMATICS
    frames = link_frames(q, kin)
    p05 = frames[5, :3, 3]
    # q1 = psi + s*phi + pi/2 with phi in [0, pi]: s = sign of the wrapped (q1 - psi - pi/2).
    psi = math.atan2(p05[1], p05[0])
    delta = math.remainder(q[0] - psi - 0.5 * math.pi, TWO_PI)
    s = 1 if delta >= 0.0 else -1
    w = 1 if math.sin(q[4]) >= 0.0 else -1
    e = 1 if math.sin(q[2]) >= 0.0 else -1
    return (s, w, e)


def inverse_kinematics_batch(
    poses: np.ndarray,
    reference_rad: Sequence[float],
    kinematics: Optional[Ur5eKinematics] = None,
    config: Optional[IkConfig] = None,
) -> Tuple[np.ndarray, np.ndarray]:
    """All branches of N poses at once, each joint on the turn inside its limits nearest the reference.

    poses: (N, 4, 4) tool0 poses; reference_rad: (6,) or (N, 6) joints [rad].
    Returns q (N, 8, 6) in BRANCHES order, a row all NaN where the branch does
    not exist or leaves the joint limits, and singular flags (N, 3) for
    (shoulder, elbow, wrist). Unsorted and not de-duplicated: the vectorised
    form of inverse_kinematics() for planners that solve many poses.
    """
    cfg = config or DEFAULT_IK_CONFIG
    t = _check_poses(poses)
    if t.ndim != 3:
        raise ValueError(f"poses must have shape (N, 4, 4), got {t.shape}")
    ref = np.asarray(reference_rad, dtype=float)
    if ref.shape not in ((NUM_JOINTS,), (t.shape[0], NUM_JOINTS)) or not np.all(np.isfinite(ref)):
        raise ValueError(f"reference joints must be 6 finite values or (N, 6), got shape {ref.shape}")
    ref = np.broadcast_to(ref, (t.shape[0], NUM_JOINTS))
    q, _, singular = ik_branches(t, ref[:, 5], kinematics, cfg)
    wrapped = wrap_into_limits(q, ref[:, None, :], np.asarray(cfg.lower_limits_rad), np.asarray(cfg.upper_limits_rad))
    wrapped[~np.all(np.isfinite(wrapped), axis=2)] = np.nan
    return wrapped, singular
