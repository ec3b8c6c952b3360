"""Run every rostest (.test file) of the workspace as one pytest case each.

rostest starts its own roscore on a free port, launches the nodes of the
.test file and runs its test nodes; a non-zero exit code means a failed or
errored test case. Driving them from pytest gives one summary line for the
whole suite. On failure the tail of rostest's output is shown.
"""
import os
import pathlib
import shutil
import subprocess

import pytest

from cottonsim_common.ros_network import ros_network_environment

ROOT = pathlib.Path(__file__).resolve().parents[1]
TEST_FILES = sorted(ROOT.glob("src/*/test/rostest/*.test")) + sorted(ROOT.glob("tests/rostest/*.test"))
TIMEOUT_S = 600


def _package_of(path: pathlib.Path) -> str:
    for parent in path.parents:
        if (parent / "package.xml").exists():
            return parent.name
    return "cottonsim_world"


def test_rostest_files_are_discovered():
    """Guards the glob above: the suite must not silently run no rostest."""
    assert TEST_FILES, "no .test files found under src/*/test/rostest or tests/rostest"


@pytest.mark.rostest
@pytest.mark.parametrize("test_file", TEST_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_rostest(test_file, tmp_path):
    if shutil.which("rostest") is None or "ROS_PACKAGE_PATH" not in os.environ:
        pytest.fail("rostest needs the built workspace: source scripts/env.sh (scripts/test.sh does)")
    try:
        env, _ = ros_network_environment(os.environ)     # the loopback when this machine's name does not resolve
    except ValueError as exc:
        pytest.fail(str(exc))
    env.update(ROS_HOME=str(tmp_path / "ros_home"), ROS_LOG_DIR=str(tmp_path / "log"))
    cmd = ["rostest", "--text", str(test_file)]
    try:
        proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired as exc:
        out = (exc.stdout or "") if isinstance(exc.stdout, str) else ""
        pytest.fail(f"rostest {test_file.name} timed out after {TIMEOUT_S} s\n{out[-6000:]}")
    output = proc.stdout + proc.stderr
    # With --text, rostest's exit code does not reflect the test result (it says so itself):
    # the SUMMARY block's RESULT line does.
    ok = proc.returncode == 0 and "* RESULT: SUCCESS" in output and "* RESULT: FAIL" not in output
    if not ok:
        pytest.fail(f"rostest {test_file.name} failed (exit {proc.returncode}):\n{output[-8000:]}")
