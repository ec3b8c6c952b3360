"""Fast CPU sensor backend: a numba z-buffer rasteriser and a numba ray caster.

Why a second backend: pybullet's TinyRenderer and rayTestBatch are the
reference, but they cost 100-900 ms per camera frame and 140-500 ms per
VLP-16 scan on the default farm, far from the paper's sensor rates. The
modules here render the same static farm (``SensorScene``) with compiled
loops over flat arrays:

* ``geometry``: flattens the farm into instanced plant models (for the
  camera) and world-space triangles (for the LiDAR);
* ``bvh``: a bounding volume hierarchy over those triangles (LiDAR);
* ``raster``: per-pixel depth-tested triangle rasteriser plus the analytic
  ground and sky of ``SensorScene.ground_and_sky``;
* ``raycast``: nearest-hit ray casting through the BVH in packets of
  neighbouring rays, ground plane analytic.

All kernels are compiled with ``cache=True`` (first use compiles for a few
seconds, later processes load the machine code from ``__pycache__``).

Threads: the parallel kernels run on numba's OpenMP threads, whose GNU
OpenMP default is to spin after each kernel, waiting for the next. Beside
other busy processes (the ROS nodes next to the bridge, a second job) a
spinning thread holds a core that the simulator's main thread needs: with
one core taken by another process, nav @ lane ran at real-time factor 3.2
with the default and 8.9 with ``OMP_WAIT_POLICY=PASSIVE`` (docs/benchmarks.md,
"OpenMP wait policy"). So this package asks for passive waiting unless the
environment says otherwise; it must be set before numba starts its
threads, i.e. before the first parallel kernel runs.
"""
import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
