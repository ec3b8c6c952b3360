"""Whole-system check: a bringup given a config file that repeats a key stops at once, saying why.

roslaunch itself keeps the last of two equal YAML keys; the simulator bridge's
executable re-reads the file it was given strictly (``--config-file=``) and,
being a required node, takes the whole launch down with one line naming the
key and both lines.
"""
import os
import pathlib
import socket
import subprocess

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_sim_launch_refuses_a_config_with_a_repeated_key(tmp_path):
    config = tmp_path / "sim.yaml"
    config.write_text("seed: 1\nfarm:\n  rows: 3\nseed: 2\n")
    port = _free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://localhost:{port}", ROS_HOME=str(tmp_path / "ros_home"))
    proc = subprocess.run(["roslaunch", "-p", str(port), "cottonsim_world", "sim.launch", f"config:={config}"],
                          cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=120)
    assert f"sim_bridge: refusing the configuration: {config}: key 'seed' is given twice, on lines 1 and 4" \
        in proc.stdout, proc.stdout[-3000:]
    assert "REQUIRED process [sim_bridge" in proc.stdout
