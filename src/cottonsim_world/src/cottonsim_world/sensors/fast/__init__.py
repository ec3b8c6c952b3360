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
"""
