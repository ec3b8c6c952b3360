"""Whole-system check: a machine whose own host name does not resolve still runs our rostests.

Cloud VMs and containers often have a host name that is neither in
/etc/hosts nor in DNS; rospy then fails every node with
``socket.gaierror: Name or service not known``. Here a private UTS namespace
(``unshare --uts``, which needs root as CI has) gives the test such a host
name, with ROS_HOSTNAME and ROS_IP unset: a plain ``rostest`` fails there
(the defect, so the check can fail), while the test harness and
``scripts/env.sh`` keep ROS on the loopback and the same rostest passes.
"""
import os
import pathlib
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DISPLAY_TEST = ROOT / "src" / "cottonsim_description" / "test" / "rostest" / "display.test"
HOSTNAME = "cottonsim-unresolvable-host"


def _in_namespace(command: str, tmp_path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("ROS_HOSTNAME", "ROS_IP")}
    env["ROS_HOME"] = str(tmp_path / "ros_home")
    return subprocess.run(["unshare", "--uts", "bash", "-c", f"hostname {HOSTNAME} && {command}"], cwd=ROOT,
                          env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)


@pytest.fixture
def can_unshare():
    if shutil.which("unshare") is None:
        pytest.skip("no unshare (util-linux) on this machine")
    probe = subprocess.run(["unshare", "--uts", "true"], capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"unshare --uts is not permitted here ({probe.stderr.strip()}); needs root")


@pytest.mark.slow
def test_rostests_run_on_a_machine_whose_host_name_does_not_resolve(can_unshare, tmp_path):
    plain = _in_namespace(f"getent hosts {HOSTNAME} || echo UNRESOLVED; rostest --text {DISPLAY_TEST}", tmp_path)
    assert "UNRESOLVED" in plain.stdout, plain.stdout[-2000:]
    assert "* RESULT: SUCCESS" not in plain.stdout, "a plain rostest passed: the namespace did not reproduce the defect"

    harness = _in_namespace(f"{sys.executable} -m pytest -q -p no:cacheprovider tests/test_rostests.py "
                            f"-k display.test", tmp_path)
    assert harness.returncode == 0 and "1 passed" in harness.stdout, harness.stdout[-4000:]

    sourced = _in_namespace("source scripts/env.sh && echo ROS_HOSTNAME=$ROS_HOSTNAME", tmp_path)
    assert "ROS_HOSTNAME=localhost" in sourced.stdout and f"'{HOSTNAME}' does not resolve" in sourced.stdout
