"""Run one roslaunch bringup as a child process: own master port, log file, progress line, clean stop.

Experiments run their bringups one after another from a plain Python
process (no rospy here): each gets a free TCP port for its own ROS master
(roslaunch starts that master and stops it at the end, so a run never
disturbs, nor is disturbed by, a roscore the user has running),
its whole console output goes to a log file, and the navigator's log lines
("goal 3/30 ... sent", "finished ...") become a one-line progress display.
When the wall-clock limit passes, the launch gets SIGINT (roslaunch then
shuts its nodes down, and the experiment recorder writes what it has), then
SIGTERM and SIGKILL if it does not end. When the launching process itself dies
(killed, or a Ray worker of a sweep whose driver was stopped), the kernel sends
roslaunch SIGINT (Linux' parent-death signal): no ROS nodes are left running.
"""
from __future__ import annotations

import ctypes
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Callable, List, Mapping, Optional

from cottonsim_common.ros_network import ros_network_environment

_GOAL_RE = re.compile(r"goal (\d+)/(\d+)")
_HOME_RE = re.compile(r"goal Home")
_FINISHED_RE = re.compile(r"finished \(([^)]*)\)")
_SUMMARY_RE = re.compile(r"(gps|map) route: CR")


def free_port() -> int:
    """A TCP port that is free right now (the kernel's pick)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class ProgressParser:
    """Turns a bringup's console lines into a short progress text."""

    label: str = ""
    text: str = "starting"

    def feed(self, line: str) -> bool:
        """Read one console line; True when the progress text changed."""
        new = None
        m = _GOAL_RE.search(line)
        if m:
            new = f"waypoint {m.group(1)}/{m.group(2)}"
        elif _HOME_RE.search(line):
            new = "returning Home"
        elif _FINISHED_RE.search(line):
            new = f"navigator finished ({_FINISHED_RE.search(line).group(1)})"
        elif _SUMMARY_RE.search(line):
            new = "report written"
        if new is None or new == self.text:
            return False
        self.text = new
        return True


@dataclass(frozen=True)
class LaunchSpec:
    """One bringup: ``roslaunch <package> <launch_file> k:=v ...`` with a wall-clock limit [s]."""

    package: str
    launch_file: str
    args: Mapping[str, object] = field(default_factory=dict)
    log_path: str = "launch.log"
    wall_timeout_s: float = 3600.0
    label: str = ""

    def __post_init__(self) -> None:
        if not self.package or not self.launch_file:
            raise ValueError("package and launch_file must be named")
        if not self.wall_timeout_s > 0.0:
            raise ValueError(f"wall_timeout_s must be > 0 s, got {self.wall_timeout_s!r}")

    def command(self, port: int) -> List[str]:
        return (["roslaunch", "-p", str(port), self.package, self.launch_file]
                + [f"{k}:={v}" for k, v in self.args.items()])


@dataclass(frozen=True)
class LaunchResult:
    returncode: Optional[int]
    timed_out: bool
    wall_s: float
    log_path: str
    aborted_reason: str = ""          # why ``on_line`` stopped the bringup early ("" when it did not)


def _print_progress(label: str, text: str, started: float) -> None:
    line = f"  [{label}] {text}  ({time.monotonic() - started:.0f} s wall)"
    if sys.stdout.isatty():
        sys.stdout.write("\r" + line.ljust(78))
    else:
        sys.stdout.write(line + "\n")
    sys.stdout.flush()


PR_SET_PDEATHSIG = 1         # prctl(2): the signal this process gets when its parent thread dies


def _child_setup(parent_pid: int) -> None:
    """In the child before exec: SIGINT unblocked and at its default action, and SIGINT when the parent dies.

    A process started from a Ray task (or any thread that blocks or ignores SIGINT) passes that on
    to its children, and a roslaunch that never sees SIGINT cannot stop its nodes cleanly. The
    child runs in a session of its own (so that a terminal's Ctrl-C reaches it through the
    launcher's orderly stop), which also means that nothing would stop it if the launcher were
    killed: the parent-death signal does.
    """
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, int(signal.SIGINT), 0, 0, 0)
        if os.getppid() != parent_pid:        # the parent died before prctl took effect
            os._exit(1)


def start_child(command: List[str], **popen_kwargs) -> subprocess.Popen:
    """Popen(command) in a session of its own, with SIGINT restored and as its parent-death signal."""
    parent = os.getpid()
    return subprocess.Popen(command, start_new_session=True, preexec_fn=lambda: _child_setup(parent),
                            **popen_kwargs)


def run_launch(spec: LaunchSpec, show_progress: bool = True,
               on_line: Optional[Callable[[str], Optional[str]]] = None) -> LaunchResult:
    """Run ``spec`` to its end (or its wall limit); returns how it ended.

    ``on_line`` sees every console line; when it returns a reason (a non-empty string) the bringup is
    stopped (SIGINT) and the reason is the result's ``aborted_reason``.
    """
    port = free_port()
    env, network_note = ros_network_environment(os.environ)      # ValueError: a ROS_HOSTNAME that does not resolve
    env["ROS_MASTER_URI"] = f"http://localhost:{port}"
    os.makedirs(os.path.dirname(os.path.abspath(spec.log_path)), exist_ok=True)
    parser = ProgressParser(spec.label)
    started = time.monotonic()
    timed_out = False
    with open(spec.log_path, "w", encoding="utf-8") as log:
        if network_note:
            log.write(f"note: {network_note}\n")
        log.write("$ " + " ".join(spec.command(port)) + "\n")
        log.flush()
        proc = start_child(spec.command(port), env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True, errors="replace")
        aborted = []

        def pump():
            for line in proc.stdout:
                log.write(line)
                reason = on_line(line) if on_line is not None else None
                if reason and not aborted:
                    aborted.append(reason)
                    log.write(f"\n[launcher] stopping: {reason}\n")
                    try:
                        os.killpg(proc.pid, signal.SIGINT)
                    except ProcessLookupError:
                        pass
                if parser.feed(line) and show_progress:
                    _print_progress(spec.label, parser.text, started)
            log.flush()

        reader = threading.Thread(target=pump, daemon=True)
        reader.start()
        try:
            proc.wait(timeout=spec.wall_timeout_s)
        except subprocess.TimeoutExpired:
            timed_out = True
            log.write(f"\n[launcher] wall-clock limit {spec.wall_timeout_s:.0f} s reached: stopping\n")
        except KeyboardInterrupt:
            stop_process_group(proc)
            raise
        finally:
            stop_process_group(proc)
            reader.join(timeout=10.0)
    if show_progress and sys.stdout.isatty():
        sys.stdout.write("\n")
    return LaunchResult(proc.returncode, timed_out, time.monotonic() - started, spec.log_path,
                        aborted[0] if aborted else "")


def stop_process_group(proc: subprocess.Popen) -> None:
    """SIGINT, then SIGTERM, then SIGKILL to the child's process group, waiting between."""
    for sig, wait_s in ((signal.SIGINT, 30.0), (signal.SIGTERM, 10.0), (signal.SIGKILL, 5.0)):
        if proc.poll() is not None:
            return
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=wait_s)
        except subprocess.TimeoutExpired:
            continue
