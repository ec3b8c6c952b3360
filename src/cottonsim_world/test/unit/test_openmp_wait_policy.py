"""The sensor kernels ask OpenMP for passive waiting, unless the user chose a policy.

numba's parallel kernels run on GNU OpenMP threads, which by default spin
after each kernel; beside another busy process on a 2-core machine that
halved the simulator's speed (docs/benchmarks.md, "OpenMP wait policy"). libgomp
reads OMP_WAIT_POLICY once, when numba first loads it, so the package that
holds the kernels must set it on import. Each case runs in a fresh
interpreter: this test process may have loaded OpenMP already.
"""
import os
import subprocess
import sys

import pytest

PROBE = ("import os, cottonsim_world.sensors.fast; "
         "print(os.environ.get('OMP_WAIT_POLICY'))")


def policy_after_import(env_policy):
    env = dict(os.environ)
    env.pop("OMP_WAIT_POLICY", None)
    if env_policy is not None:
        env["OMP_WAIT_POLICY"] = env_policy
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=120,
                         check=True)
    return out.stdout.strip().splitlines()[-1]


def test_passive_by_default():
    assert policy_after_import(None) == "PASSIVE"


@pytest.mark.parametrize("chosen", ["ACTIVE", "passive"])
def test_a_policy_set_by_the_user_is_kept(chosen):
    assert policy_after_import(chosen) == chosen
