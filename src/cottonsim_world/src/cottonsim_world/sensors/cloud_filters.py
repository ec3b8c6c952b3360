"""Point cloud filters of the original's navigation pipeline (numpy, numba for the per-revolution ones).

Why: the original ran PCL's PassThrough filter on the VLP-16 cloud
(/points -> /passthrough/output, for the local costmap) and the
pointcloud_to_laserscan node (-> the scan used by gmapping / AMCL). These
are vectorised re-implementations of both, so the bridge needs neither PCL
nor those ROS packages:

* ``passthrough``: keep points whose coordinate on one axis lies in
  [min, max] (inclusive, NaN dropped), as pcl::PassThrough does.
* ``cloud_to_laserscan``: per angle bin the nearest planar range of the
  points in a height slice, as pointcloud_to_laserscan does: points with
  z outside [min_height, max_height], planar range outside [range_min,
  range_max] or angle outside [angle_min, angle_max] are ignored; bin index
  = floor((angle - angle_min) / angle_increment); bin count =
  ceil((angle_max - angle_min) / angle_increment); empty bins are +inf
  (the node's use_inf default true) or range_max + 1 with use_inf false.

The simulator runs ``original_passthrough`` and ``cloud_to_laserscans`` on
every VLP-16 revolution; both are one compiled pass over the cloud
(``sensors.fast.cloud_kernels``, ~10x fewer instructions): the PassThrough
is the numpy mask bit for bit, the LaserScans the numpy scans up to the
rounding of atan2 / hypot (see cloud_kernels). The other functions stay plain numpy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Sequence, Tuple, Union

import numpy as np

from cottonsim_world.sensors.fast.cloud_kernels import laserscans_into, passthrough_yz

_AXES = {"x": 0, "y": 1, "z": 2}


def _check_points(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] < 3:
        raise ValueError(f"points must be an (N, 3) array, got shape {pts.shape}")
    return pts


def passthrough_mask(points: np.ndarray, axis: Union[str, int], min_m: float, max_m: float) -> np.ndarray:
    """Boolean (N,) mask of the points with min_m <= points[:, axis] <= max_m."""
    pts = _check_points(points)
    if isinstance(axis, str):
        if axis not in _AXES:
            raise ValueError(f"axis must be 'x', 'y', 'z' or 0-2, got {axis!r}")
        axis = _AXES[axis]
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 'x', 'y', 'z' or 0-2, got {axis!r}")
    if not (min_m <= max_m):
        raise ValueError(f"passthrough limits need min_m <= max_m, got {min_m}, {max_m}")
    v = pts[:, axis]
    with np.errstate(invalid="ignore"):
        return (v >= min_m) & (v <= max_m)


def passthrough(points: np.ndarray, axis: Union[str, int], min_m: float, max_m: float) -> np.ndarray:
    """The points whose coordinate on ``axis`` lies in [min_m, max_m]."""
    pts = _check_points(points)
    return pts[passthrough_mask(pts, axis, min_m, max_m)]


@dataclass(frozen=True)
class PassThroughConfig:
    """The original's chained PassThrough filters in the velodyne frame [m]."""

    y_min_m: float = -10.0
    y_max_m: float = 0.0
    z_min_m: float = 0.0
    z_max_m: float = 0.5

    def __post_init__(self) -> None:
        if not self.y_min_m <= self.y_max_m:
            raise ValueError(f"y_min_m must be <= y_max_m, got {self.y_min_m}, {self.y_max_m}")
        if not self.z_min_m <= self.z_max_m:
            raise ValueError(f"z_min_m must be <= z_max_m, got {self.z_min_m}, {self.z_max_m}")


def original_passthrough_mask(points: np.ndarray, config: PassThroughConfig = PassThroughConfig()) -> np.ndarray:
    """Mask of the points kept by the original's y-then-z PassThrough chain."""
    return (passthrough_mask(points, "y", config.y_min_m, config.y_max_m)
            & passthrough_mask(points, "z", config.z_min_m, config.z_max_m))


def original_passthrough(points: np.ndarray, config: PassThroughConfig = PassThroughConfig()) -> np.ndarray:
    """The points kept by the original's y-then-z PassThrough chain: ``points[original_passthrough_mask(...)]``.

    Float clouds take one compiled pass (the limits cast to the cloud's
    dtype, as numpy's comparison does); other dtypes the numpy mask.
    """
    pts = _check_points(points)
    if pts.dtype not in (np.float32, np.float64):
        return pts[original_passthrough_mask(pts, config)]
    as_dtype = pts.dtype.type
    return passthrough_yz(pts, as_dtype(config.y_min_m), as_dtype(config.y_max_m), as_dtype(config.z_min_m),
                          as_dtype(config.z_max_m))


@dataclass(frozen=True)
class LaserScanConfig:
    """pointcloud_to_laserscan parameters; defaults: the original's launch file.

    Heights and ranges in [m], angles in [rad] in the cloud's frame (the
    velodyne frame, yawed +90 deg on the robot, so -2.356..-0.785 is the
    robot's forward +/-45 deg sector).
    """

    min_height_m: float = 0.0
    max_height_m: float = 0.1
    angle_min_rad: float = -2.35619
    angle_max_rad: float = -0.785398
    angle_increment_rad: float = 0.0087
    range_min_m: float = 0.2
    range_max_m: float = 20.0
    use_inf: bool = True

    def __post_init__(self) -> None:
        if not self.min_height_m <= self.max_height_m:
            raise ValueError(f"min_height_m must be <= max_height_m, got {self.min_height_m}, {self.max_height_m}")
        if not (-math.pi <= self.angle_min_rad < self.angle_max_rad <= math.pi):
            raise ValueError(f"angle_min_rad/angle_max_rad must satisfy -pi <= min < max <= pi, got "
                             f"{self.angle_min_rad}, {self.angle_max_rad}")
        if not (self.angle_increment_rad > 0.0):
            raise ValueError(f"angle_increment_rad must be > 0, got {self.angle_increment_rad}")
        if self.bin_count > 100_000:
            raise ValueError(f"angle_increment_rad {self.angle_increment_rad} gives too many bins ({self.bin_count})")
        if not (0.0 <= self.range_min_m < self.range_max_m) or not math.isfinite(self.range_max_m):
            raise ValueError(f"range_min_m/range_max_m must satisfy 0 <= min < max < inf, got "
                             f"{self.range_min_m}, {self.range_max_m}")

    @property
    def bin_count(self) -> int:
        return int(math.ceil((self.angle_max_rad - self.angle_min_rad) / self.angle_increment_rad))

    def bin_angles_rad(self) -> np.ndarray:
        """Angle of each bin's start, as LaserScan's angle_min + i * increment."""
        return self.angle_min_rad + self.angle_increment_rad * np.arange(self.bin_count)


def cloud_to_laserscan(points: np.ndarray, config: LaserScanConfig = LaserScanConfig()) -> np.ndarray:
    """Ranges (bin_count,) float32 [m] of the nearest point per angle bin."""
    return cloud_to_laserscans(points, (config,))[0]


def cloud_to_laserscans(points: np.ndarray, configs: Sequence[LaserScanConfig]) -> List[np.ndarray]:
    """``cloud_to_laserscan`` of one cloud for several configurations (same results, one call each).

    The planar range and the angle of a point are computed once, and only
    for points inside some scan's height slice, and shared by the scans
    (the bridge makes the forward and the 360 deg scan of each VLP-16
    revolution); one compiled pass, ``cloud_kernels.laserscans_into``.
    """
    pts = _check_points(points)
    if pts.dtype not in (np.float32, np.float64):
        pts = pts.astype(np.float64)
    configs = list(configs)
    limits = np.array([(c.min_height_m, c.max_height_m, c.range_min_m, c.range_max_m, c.angle_min_rad,
                        c.angle_max_rad, c.angle_increment_rad) for c in configs], dtype=np.float64).reshape(-1, 7)
    bin_counts = np.array([c.bin_count for c in configs], dtype=np.int64)
    ranges = np.full((len(configs), int(bin_counts.max(initial=0))), np.inf)
    for k, config in enumerate(configs):
        if not config.use_inf:
            ranges[k] = config.range_max_m + 1.0
    laserscans_into(pts, limits, bin_counts, ranges)
    return [ranges[k, :config.bin_count].astype(np.float32) for k, config in enumerate(configs)]
