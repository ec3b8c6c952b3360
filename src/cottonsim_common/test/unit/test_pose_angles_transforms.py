"""The shared planar pose, angle wrap and quaternion helpers of cottonsim_common."""
import math

import numpy as np
import pytest

from cottonsim_common.angles import shortest_angular_distance, wrap_angle, wrap_angle_scalar
from cottonsim_common.pose import Pose2D, as_pose, compose, frame_to_world, inverse, transform_points, world_to_frame
from cottonsim_common.transforms import (invert, matrix_to_quaternion, pose_matrix, quaternion_to_matrix,
                                         quaternion_to_yaw, yaw_of, yaw_to_quaternion)
from cottonsim_common.transforms import transform_points as transform_points_3d


def test_wrap_angle_range_scalars_and_arrays():
    assert wrap_angle(3 * math.pi) == pytest.approx(-math.pi)
    assert wrap_angle(math.pi) == pytest.approx(-math.pi)          # [-pi, pi): pi maps to -pi
    assert isinstance(wrap_angle(7.0), float)
    a = wrap_angle(np.array([0.0, 4.0, -4.0, 10.0]))
    assert isinstance(a, np.ndarray) and np.all(a >= -math.pi) and np.all(a < math.pi)
    np.testing.assert_allclose(np.cos(a), np.cos([0.0, 4.0, -4.0, 10.0]), atol=1e-12)
    assert wrap_angle_scalar(-math.pi - 0.1) == pytest.approx(math.pi - 0.1)


def test_shortest_angular_distance_crosses_pi():
    assert shortest_angular_distance(math.radians(170), math.radians(-170)) == pytest.approx(math.radians(20))
    np.testing.assert_allclose(shortest_angular_distance(np.array([0.0, 3.0]), np.array([0.5, -3.0])),
                               [0.5, 2 * math.pi - 6.0])


def test_pose_validates_and_composes():
    with pytest.raises(ValueError, match="Pose2D.y_m"):
        Pose2D(0.0, float("nan"))
    a, b = Pose2D(1.0, 2.0, 0.5), Pose2D(-0.3, 0.7, -1.2)
    ident = compose(a, inverse(a))
    assert (ident.x_m, ident.y_m, ident.yaw_rad) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    c = compose(a, b)
    x, y = transform_points(a, [[b.x_m, b.y_m]])[0]
    assert (c.x_m, c.y_m) == pytest.approx((x, y))
    assert as_pose((1, 2)) == Pose2D(1.0, 2.0, 0.0)
    with pytest.raises(ValueError, match="x, y"):
        as_pose((1, 2, 3, 4))


def test_frames_round_trip():
    frame = Pose2D(-6.0, 1.0, math.pi / 2)
    x, y, yaw = world_to_frame(frame, 2.0, 5.0, 0.3)
    assert (float(x), float(y)) == pytest.approx((4.0, -8.0))
    xw, yw, yaww = frame_to_world(frame, x, y, yaw)
    assert (float(xw), float(yw), float(yaww)) == pytest.approx((2.0, 5.0, 0.3))


def test_quaternions_xyzw_and_matrices():
    q = yaw_to_quaternion(1.0)
    assert q[:2] == (0.0, 0.0) and q[2] == pytest.approx(math.sin(0.5))      # xyzw: w last
    assert quaternion_to_yaw(*q) == pytest.approx(1.0)
    assert yaw_of(q) == pytest.approx(1.0)
    assert quaternion_to_yaw(0.0, 0.0, 2 * q[2], 2 * q[3]) == pytest.approx(1.0)   # normalised first
    with pytest.raises(ValueError, match="zero length"):
        quaternion_to_yaw(0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="non-finite"):
        quaternion_to_yaw(0.0, 0.0, float("nan"), 1.0)
    r = quaternion_to_matrix(q)
    assert np.allclose(matrix_to_quaternion(r), q)
    t = pose_matrix((1.0, 2.0, 3.0), q)
    assert np.allclose(invert(t) @ t, np.eye(4))
    assert yaw_of(t) == pytest.approx(1.0)


def test_transform_points_by_a_matrix():
    # frame b rotated +90 deg about z and shifted by (1, 0, 0) in frame a: b's x is a's y
    a_T_b = pose_matrix((1.0, 0.0, 0.0), yaw_to_quaternion(math.pi / 2))
    p = transform_points_3d(a_T_b, np.array([[1.0, 0.0, 0.0], [np.nan] * 3]))
    assert p[0] == pytest.approx([1.0, 1.0, 0.0])
    assert np.isnan(p[1]).all()
    assert transform_points_3d(a_T_b, [0.0, 0.0, 2.0]).tolist() == [[1.0, 0.0, 2.0]]
    for bad in (np.eye(3), np.full((4, 4), np.nan)):
        with pytest.raises(ValueError, match="finite 4x4"):
            transform_points_3d(bad, [[0.0, 0.0, 0.0]])
