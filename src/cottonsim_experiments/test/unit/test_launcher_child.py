"""The launcher's children: a roslaunch must not outlive the process that started it."""
import os
import subprocess
import sys
import time

import pytest

from cottonsim_experiments.reproduce.launcher import start_child

LAUNCHER = """
import sys, time
from cottonsim_experiments.reproduce.launcher import start_child
child = start_child([sys.executable, "-c", "import time; time.sleep(60)"])
print(child.pid, flush=True)
time.sleep(60)
"""


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"      # a zombie has ended
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the parent-death signal is Linux's")
def test_a_child_is_stopped_when_its_launcher_is_killed():
    launcher = subprocess.Popen([sys.executable, "-c", LAUNCHER], stdout=subprocess.PIPE, text=True)
    try:
        child_pid = int(launcher.stdout.readline())
        assert _alive(child_pid)
        launcher.kill()                                     # SIGKILL: no cleanup of its own runs
        launcher.wait()
        deadline = time.monotonic() + 10.0
        while _alive(child_pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(child_pid), "the child outlived its killed launcher"
    finally:
        launcher.kill()


def test_a_child_runs_in_its_own_session_with_sigint_at_its_default():
    child = start_child([sys.executable, "-c", "import os, signal; "
                         "print(os.getsid(0) == os.getpid(), signal.getsignal(signal.SIGINT) is signal.default_int_handler)"],
                        stdout=subprocess.PIPE, text=True)
    out, _ = child.communicate(timeout=30)
    assert out.split() == ["True", "True"]                  # Python installs its handler when SIGINT is at default
    assert os.getsid(0) != child.pid
