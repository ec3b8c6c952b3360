"""Numba kernels of the VLP-16 cloud filters (``sensors.cloud_filters``): PassThrough and LaserScans.

Why: every 10 Hz VLP-16 reading runs the PassThrough filter and two
LaserScans on its ~9,000-14,000 points. As numpy expressions they took
~6 M instructions a revolution in a crop lane (~60 M per simulated second,
about as much as the physics step): a dozen passes over the cloud,
``np.minimum.at`` (a slow ufunc.at in numpy 1.24) and ``hypot`` / ``atan2``
of every point, although only the points in a scan's height slice need
them. Here each filter is one pass over the points, and a point's planar
range and angle are computed only when a scan's height slice holds it.

What is promised, on every x86-64 CPU:

* the PassThrough is the numpy mask bit for bit: it only compares (the
  limits in the cloud's own dtype, as numpy 1.24 compares a float32 array
  with a Python float);
* the LaserScans are the numpy scans up to the rounding of ``atan2`` and
  ``hypot``: the same truncation of the bin index and the same
  nearest-range rule, but the math library's last bit differs between CPUs
  (numpy picks AVX-512 or AVX2 kernels by CPU, glibc has FMA variants; on
  an AVX-512 machine numpy's ``arctan2`` differs from libm's ``atan2`` by
  an ulp in about a third of the points). So a range may move by an ulp,
  and a point within ~1e-12 rad of a bin edge or a limit may fall into the
  neighbouring bin. On one machine a run is repeatable bit for bit.

``test_lidar.py`` checks both against the numpy reference, and
``tests/test_cpu_independence.py`` re-runs the kernel tests compiled for a
baseline x86-64 CPU with numpy's AVX-512 kernels off.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def passthrough_yz(points, y_min, y_max, z_min, z_max):  # pragma: no cover
    """The rows of points (N, >= 3) with y_min <= y <= y_max and z_min <= z <= z_max, in order.

    NaN fails every comparison, so NaN rows are dropped (pcl::PassThrough's
    behaviour). The limits should carry the points' dtype (the caller casts
    them) so that the comparisons are those numpy makes. Returns a new
    (M, 3) array of the points' dtype.
    """
    n = points.shape[0]
    keep = np.zeros(n, np.bool_)
    count = 0
    for i in range(n):
        y = points[i, 1]
        z = points[i, 2]
        if y >= y_min and y <= y_max and z >= z_min and z <= z_max:
            keep[i] = True
            count += 1
    out = np.empty((count, 3), points.dtype)
    k = 0
    for i in range(n):
        if keep[i]:
            out[k, 0] = points[i, 0]
            out[k, 1] = points[i, 1]
            out[k, 2] = points[i, 2]
            k += 1
    return out


@njit(cache=True, nogil=True)
def laserscans_into(points, limits, bin_counts, ranges):  # pragma: no cover
    """Nearest planar range per angle bin of several LaserScans of one cloud, into ``ranges``.

    points (N, >= 3) [m], any float dtype (used as float64). limits (K, 7)
    float64, per scan: min and max height [m], min and max planar range
    [m], min and max angle [rad], angle increment [rad]. bin_counts (K,)
    int64. ranges (K, max bin count) float64, filled by the caller with
    each scan's value for an empty bin; a kept point lowers its bin to its
    planar range if nearer. A point is kept by scan k when its z, planar
    range hypot(x, y) and angle atan2(y, x) all lie in scan k's closed
    intervals (NaN never does); its bin is
    min(int((angle - min angle) / increment), bin count - 1).
    """
    n = points.shape[0]
    n_scans = limits.shape[0]
    for i in range(n):
        z = np.float64(points[i, 2])
        r = 0.0
        angle = 0.0
        planar_done = False
        for k in range(n_scans):
            if not (z >= limits[k, 0] and z <= limits[k, 1]):
                continue
            if not planar_done:         # only points inside some height slice pay for hypot / atan2
                x = np.float64(points[i, 0])
                y = np.float64(points[i, 1])
                r = math.hypot(x, y)
                angle = math.atan2(y, x)
                planar_done = True
            if not (r >= limits[k, 2] and r <= limits[k, 3] and angle >= limits[k, 4] and angle <= limits[k, 5]):
                continue
            b = np.int64((angle - limits[k, 4]) / limits[k, 6])
            last = bin_counts[k] - 1
            if b > last:
                b = last
            if r < ranges[k, b]:
                ranges[k, b] = r
