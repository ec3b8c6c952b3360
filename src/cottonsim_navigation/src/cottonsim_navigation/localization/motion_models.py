"""Odometry motion model of a differential-drive robot (sampling form).

Why: AMCL and the SLAM particle filter both move every particle by the
odometry measured since the last filter update, with noise that grows with
the distance driven and the angle turned. This is the ``diff`` model of ROS
amcl, which is Probabilistic Robotics' ``sample_motion_model_odometry``
(Table 5.6): the odometry increment between two odometry poses is split into
a first rotation ``rot1`` (towards the direction of travel), a translation
``trans`` and a second rotation ``rot2``; each part is perturbed with
zero-mean Gaussian noise built from

    rot1, rot2:  q_rot   = alpha1 * rot^2   + alpha2 * trans^2
    trans:       q_trans = alpha3 * trans^2 + alpha4 * (rot1^2 + rot2^2)

and the perturbed increment is applied to every particle in its own frame.

Two ways of turning q into noise exist in ROS amcl (``odom_model_type``):

* ``"diff"`` (amcl's original model, the one the original CottonSim and the
  Husky configuration use): q is passed to the Gaussian sampler as the
  *standard deviation* [rad or m]. For the 0.25 m filter step of the original
  (alpha 0.2) that is a heading noise of 0.0125 rad per step.
* ``"diff-corrected"`` (Probabilistic Robotics, amcl's bug-fixed model): q is
  the *variance*, the noise's standard deviation is sqrt(q). With alpha 0.2 the
  same 0.25 m step gets 0.11 rad of heading noise, nine times more; the
  original's alphas were tuned for ``"diff"``. Using them with the corrected
  form spread AMCL's particles faster than a crop-row scan can pull them
  together (the particle set never converged in the farm).

As in ROS amcl, the rotation noise of a backwards step uses the rotation
angle folded to the nearest of 0 and pi (driving backwards is not a 180 deg
turn), and for steps below 1 cm ``rot1`` is 0 (the direction of a tiny step
is noise). alpha5 exists only for the omni-directional model; it is kept for
parameter compatibility and unused here.

Late updates (not in ROS amcl): the diff model's noise grows with the
*square* of the step, so one increment of 2 m gets 64x the spread of a
0.25 m step, not the 8 x 0.25 m steps' sqrt(8)x. A filter that falls behind
(a busy machine, a simulator running faster than the node: scans dropped, the
next update covers metres) would then scatter its particles over the
neighbouring crop lanes. With ``max_step_m`` / ``max_step_rad`` > 0, an
increment longer or turning more than that is split into equal parts along
the constant-velocity arc between the two odometry poses (SE(2) exp / log;
the parts compose exactly to the increment), each sampled with its own noise:
the noise no longer depends on how often the filter ran. At most
``MAX_SUBSTEPS`` parts (an odometry jump of kilometres must not stall the
filter); 0 = never split, ROS amcl's behaviour.

Everything is vectorised over particles: poses are (N, 3) arrays of
(x_m, y_m, yaw_rad).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from cottonsim_common.angles import wrap_angle
from cottonsim_common.validation import require_fields

# Below this translation [m] the heading of the step is not meaningful (ROS amcl: 0.01 m).
MIN_TRANSLATION_FOR_HEADING_M = 0.01

# Most parts one late odometry increment is split into (see the module docstring).
MAX_SUBSTEPS = 64

# odom_model_type values (see the module docstring).
MOTION_MODELS = ("diff", "diff-corrected")


@dataclass(frozen=True)
class OdometryMotionModelConfig:
    """Noise of the differential odometry model (ROS amcl odom_alpha1..5; the original's values).

    alpha1: rotation noise from rotation [rad^2 / rad^2];
    alpha2: rotation noise from translation [rad^2 / m^2];
    alpha3: translation noise from translation [m^2 / m^2];
    alpha4: translation noise from rotation [m^2 / rad^2];
    alpha5: translation noise of the omni model (unused by the diff model);
    model: "diff" (ROS amcl's original sampling: the alpha expression is the noise's standard
        deviation; the original's odom_model_type) or "diff-corrected" (it is the variance);
    max_step_m [m], max_step_rad [rad]: an increment longer / turning more than this is sampled as
        equal parts (see the module docstring); 0 (default) = always in one piece, as ROS amcl.
    """

    alpha1: float = 0.2
    alpha2: float = 0.2
    alpha3: float = 0.2
    alpha4: float = 0.2
    alpha5: float = 0.1
    model: str = "diff"
    max_step_m: float = 0.0
    max_step_rad: float = 0.0

    def __post_init__(self) -> None:
        require_fields(self, non_negative=("alpha1", "alpha2", "alpha3", "alpha4", "alpha5", "max_step_m",
                                           "max_step_rad"))
        if self.model not in MOTION_MODELS:
            raise ValueError(f"model must be one of {MOTION_MODELS}, got {self.model!r}")

    def noise_sd(self, q: float) -> float:
        """Standard deviation of the noise for the alpha expression ``q`` (see the module docstring)."""
        return q if self.model == "diff" else math.sqrt(q)


def _as_pose_array(pose, name: str) -> np.ndarray:
    """(3,) float array from a Pose2D-like object or a sequence; ValueError naming ``name``."""
    if hasattr(pose, "x_m"):
        arr = np.array([pose.x_m, pose.y_m, getattr(pose, "yaw_rad", 0.0)], dtype=float)
    else:
        try:
            arr = np.asarray(pose, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be (x_m, y_m, yaw_rad), got {pose!r}") from None
    if arr.shape != (3,):
        raise ValueError(f"{name} must have 3 values (x_m, y_m, yaw_rad), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return arr


def odometry_increment(odom_prev, odom_now) -> Tuple[float, float, float]:
    """Split the odometry step into (rot1_rad, trans_m, rot2_rad) as ROS amcl does."""
    p0 = _as_pose_array(odom_prev, "odom_prev")
    p1 = _as_pose_array(odom_now, "odom_now")
    dx, dy = p1[0] - p0[0], p1[1] - p0[1]
    trans = math.hypot(dx, dy)
    if trans < MIN_TRANSLATION_FOR_HEADING_M:
        rot1 = 0.0
    else:
        rot1 = wrap_angle(math.atan2(dy, dx) - p0[2])
    rot2 = wrap_angle(wrap_angle(p1[2] - p0[2]) - rot1)
    return rot1, trans, rot2


def _se2_log(dx: float, dy: float, dyaw: float) -> Tuple[float, float, float]:
    """Twist (vx, vy, w) whose constant-velocity motion for unit time gives the relative pose (dx, dy, dyaw)."""
    if abs(dyaw) < 1e-9:
        return dx, dy, dyaw
    a = math.sin(dyaw) / dyaw                       # V = [[a, -b], [b, a]], (dx, dy) = V (vx, vy)
    b = (1.0 - math.cos(dyaw)) / dyaw
    det = a * a + b * b
    return (a * dx + b * dy) / det, (-b * dx + a * dy) / det, dyaw


def _se2_exp(vx: float, vy: float, w: float) -> Tuple[float, float, float]:
    """Relative pose (dx, dy, dyaw) after unit time at the constant twist (vx, vy, w)."""
    if abs(w) < 1e-9:
        return vx, vy, w
    a = math.sin(w) / w
    b = (1.0 - math.cos(w)) / w
    return a * vx - b * vy, b * vx + a * vy, w


def _increment_twist(p0: np.ndarray, p1: np.ndarray) -> Tuple[float, float, float]:
    """The twist (in p0's frame) of the constant-velocity arc from odometry pose p0 to p1."""
    c, s = math.cos(p0[2]), math.sin(p0[2])
    gx, gy = p1[0] - p0[0], p1[1] - p0[1]
    return _se2_log(c * gx + s * gy, -s * gx + c * gy, float(wrap_angle(p1[2] - p0[2])))


def _parts_for(twist: Tuple[float, float, float], max_step_m: float, max_step_rad: float) -> int:
    """Fewest equal parts of the arc with none longer than max_step_m nor turning more than max_step_rad
    (a limit <= 0 is ignored), capped at MAX_SUBSTEPS."""
    k = 1
    if max_step_m > 0:
        k = max(k, math.ceil(math.hypot(twist[0], twist[1]) / max_step_m - 1e-9))
    if max_step_rad > 0:
        k = max(k, math.ceil(abs(twist[2]) / max_step_rad - 1e-9))
    return min(k, MAX_SUBSTEPS)


def motion_parts(odom_prev, odom_now, config: OdometryMotionModelConfig) -> int:
    """How many parts :func:`sample_motion_model_odometry` samples this increment in (1: in one piece;
    more: a late update, see the module docstring)."""
    if config.max_step_m <= 0 and config.max_step_rad <= 0:
        return 1
    twist = _increment_twist(_as_pose_array(odom_prev, "odom_prev"), _as_pose_array(odom_now, "odom_now"))
    return _parts_for(twist, config.max_step_m, config.max_step_rad)


def split_odometry_increment(odom_prev, odom_now, max_step_m: float, max_step_rad: float) -> np.ndarray:
    """Odometry poses (k + 1, 3) from ``odom_prev`` to ``odom_now`` in k equal parts of the arc between them.

    k is the fewest parts with no part longer than ``max_step_m`` nor turning more than ``max_step_rad``
    (a limit <= 0 is ignored), capped at MAX_SUBSTEPS; the first row is odom_prev, the last odom_now.
    """
    p0 = _as_pose_array(odom_prev, "odom_prev")
    p1 = _as_pose_array(odom_now, "odom_now")
    c, s = math.cos(p0[2]), math.sin(p0[2])
    twist = _increment_twist(p0, p1)
    k = _parts_for(twist, max_step_m, max_step_rad)
    poses = np.empty((k + 1, 3))
    poses[0], poses[k] = p0, p1
    for i in range(1, k):
        dx, dy, dyaw = _se2_exp(*(v * i / k for v in twist))
        poses[i] = (p0[0] + c * dx - s * dy, p0[1] + s * dx + c * dy, wrap_angle(p0[2] + dyaw))
    return poses


def sample_motion_model_odometry(particles: np.ndarray, odom_prev, odom_now,
                                 config: OdometryMotionModelConfig = OdometryMotionModelConfig(),
                                 rng: Optional[np.random.Generator] = None) -> np.ndarray:
    """Move every particle by the noisy odometry increment ``odom_prev -> odom_now``.

    particles: (N, 3) poses (x_m, y_m, yaw_rad) in the map frame;
    odom_prev, odom_now: odometry poses (x_m, y_m, yaw_rad) in the odom frame;
    returns a new (N, 3) array (the input is not modified), yaws in [-pi, pi).
    An increment beyond config.max_step_m / max_step_rad is sampled in parts (see the module docstring).
    """
    parts = np.asarray(particles, dtype=float)
    if parts.ndim != 2 or parts.shape[1] != 3:
        raise ValueError(f"particles must be an (N, 3) array of (x_m, y_m, yaw_rad), got shape {parts.shape}")
    if rng is None:
        rng = np.random.default_rng()
    if config.max_step_m > 0 or config.max_step_rad > 0:
        steps = split_odometry_increment(odom_prev, odom_now, config.max_step_m, config.max_step_rad)
        if len(steps) > 2:
            for a, b in zip(steps[:-1], steps[1:]):
                parts = _sample_one_increment(parts, a, b, config, rng)
            return parts
    return _sample_one_increment(parts, odom_prev, odom_now, config, rng)


def _sample_one_increment(parts: np.ndarray, odom_prev, odom_now, config: OdometryMotionModelConfig,
                          rng: np.random.Generator) -> np.ndarray:
    rot1, trans, rot2 = odometry_increment(odom_prev, odom_now)
    # A backwards step should not look like a half turn to the noise model.
    rot1_noise = min(abs(wrap_angle(rot1)), abs(wrap_angle(rot1 - math.pi)))
    rot2_noise = min(abs(wrap_angle(rot2)), abs(wrap_angle(rot2 - math.pi)))
    a = config
    sd_rot1 = a.noise_sd(a.alpha1 * rot1_noise ** 2 + a.alpha2 * trans ** 2)
    sd_trans = a.noise_sd(a.alpha3 * trans ** 2 + a.alpha4 * (rot1_noise ** 2 + rot2_noise ** 2))
    sd_rot2 = a.noise_sd(a.alpha1 * rot2_noise ** 2 + a.alpha2 * trans ** 2)
    n = parts.shape[0]
    r1 = rot1 - sd_rot1 * rng.standard_normal(n)
    tr = trans - sd_trans * rng.standard_normal(n)
    r2 = rot2 - sd_rot2 * rng.standard_normal(n)
    out = np.empty_like(parts)
    heading = parts[:, 2] + r1
    out[:, 0] = parts[:, 0] + tr * np.cos(heading)
    out[:, 1] = parts[:, 1] + tr * np.sin(heading)
    out[:, 2] = wrap_angle(parts[:, 2] + r1 + r2)
    return out
