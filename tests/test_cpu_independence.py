"""House rule: a user's CPU must not fail our tests.

The sensor and estimation kernels are compiled by numba for the CPU they run
on, and numpy picks SIMD kernels (AVX2, AVX-512) by CPU at import. A test
that compares a kernel with a numpy reference bit for bit can therefore pass
on our machines and fail on a user's. Here the kernel tests run once more in
a fresh interpreter with numba compiling for a baseline x86-64 CPU
(``NUMBA_CPU_NAME=generic``: SSE2, no FMA, no AVX) and numpy's AVX-512
kernels switched off, i.e. as an older or smaller CPU would run them; what
each kernel promises across CPUs is written in its module docstring.
"""
import os
import pathlib
import platform
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
UNIT = ROOT / "src" / "cottonsim_world" / "test" / "unit"
# the tests that hold a compiled kernel to a reference (numpy, a list implementation, a brute force)
KERNEL_TESTS = ["test_lidar.py", "test_triangle_bvh.py", "test_fast_sensors.py", "test_odometry_ekf.py"]


def _numpy_avx512_features():
    """numpy's dispatched AVX-512 features that this CPU has (numpy warns about naming any other)."""
    from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    return [name for name in __cpu_dispatch__ if name.startswith("AVX512") and __cpu_features__.get(name)]


@pytest.mark.slow
@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"),
                    reason="the baseline target named here is x86-64's; other architectures compile for themselves")
def test_kernel_tests_pass_compiled_for_a_baseline_x86_64_cpu(tmp_path):
    env = dict(os.environ, NUMBA_CPU_NAME="generic", NUMBA_CACHE_DIR=str(tmp_path / "numba_cache"),
               NPY_DISABLE_CPU_FEATURES=" ".join(_numpy_avx512_features()))
    probe = subprocess.run([sys.executable, "-c", "import numba, numpy; from numpy.core._multiarray_umath import "
                            "__cpu_features__ as f; print(numba.config.CPU_NAME, f.get('AVX512F'))"],
                           env=env, capture_output=True, text=True, timeout=120)
    assert probe.returncode == 0, probe.stderr
    assert probe.stdout.split() == ["generic", "False"]          # the emulation is in force
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           *[str(UNIT / name) for name in KERNEL_TESTS]],
                          cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=1500)
    assert proc.returncode == 0, proc.stdout[-4000:]
    passed = re.search(r"(\d+) passed", proc.stdout)
    assert passed and int(passed.group(1)) >= 40, proc.stdout[-2000:]      # the kernel tests ran (42 today)
