#!/usr/bin/env python3
"""Cotton-Eye in the loop: perception CPU seconds per sim second and the real-time factor of a driven run.

Starts ``perception_demo.launch`` (the simulator with its three cameras as in
config/sim.yaml, the perception nodes of perception.launch and the route
driver on the farm's default route) on a ROS master port of its own, as fast as
it can go (real_time_factor 0, or --real-time-factor), and measures over a
window of sim time after a warm-up:

* CPU seconds (user + system, all threads, from /proc) per sim second of each
  node, the perception nodes' sum, and of the simulator bridge;
* the real-time factor (sim seconds per wall second) of the window;
* the perception outputs per sim second (label images, row-centring commands,
  boll detections of each side camera);
* the simulator's own timings at the end of the window (/sim/stats: ms per
  physics step, mean ms per update of each sensor since the start).

It measures the perception nodes of whatever workspace is sourced: to compare
two trees, source each one's scripts/env.sh and run this script from either.

  python benchmarks/bench_perception_loop.py [--warmup-s 20] [--window-s 60] [--mask-source network]
         [--arg NAME:=VALUE ...] [--launch-file FILE]

Exit code 0, or 2 with one line if the bringup did not reach the window in --timeout-s of wall time.
"""
import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
import xmlrpc.client

PERCEPTION_PREFIXES = ("/segmentation", "/row_centring", "/boll_detection")
BRIDGE = "/sim_bridge"
COUNTED_TOPICS = ("/segmentation/labels", "/husky/cv/coords", "/boll_detection_left/detections",
                  "/boll_detection_right/detections")


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process (all its threads) so far."""
    with open(f"/proc/{pid}/stat") as fh:
        fields = fh.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def node_pids(master_uri: str) -> dict:
    """node name -> pid of every node registered with the master."""
    import rosgraph

    master = rosgraph.Master("/bench_perception_loop", master_uri=master_uri)
    names = set()
    for group in master.getSystemState():
        for _topic, nodes in group:
            names.update(nodes)
    pids = {}
    for name in sorted(names):
        try:
            code, _msg, pid = xmlrpc.client.ServerProxy(master.lookupNode(name)).getPid("/bench")
        except Exception:           # a node that went away meanwhile
            continue
        if code == 1:
            pids[name] = pid
    return pids


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--warmup-s", type=float, default=20.0, help="sim seconds before the window (default 20)")
    ap.add_argument("--window-s", type=float, default=60.0, help="sim seconds measured (default 60)")
    ap.add_argument("--real-time-factor", type=float, default=0.0, help="0 = as fast as possible (default)")
    ap.add_argument("--mask-source", default="network", help="network (default) | ground_truth")
    ap.add_argument("--arg", action="append", default=[], help="more perception_demo.launch args, NAME:=VALUE")
    ap.add_argument("--launch-file", default=None,
                    help="a launch file to run instead of perception_demo.launch (e.g. other node settings)")
    ap.add_argument("--timeout-s", type=float, default=900.0, help="wall-time limit (default 900)")
    a = ap.parse_args()
    if a.warmup_s < 0 or a.window_s <= 0:
        ap.error("--warmup-s must be >= 0 and --window-s > 0")
    port = 11400 + random.randrange(500)
    master_uri = f"http://localhost:{port}"
    env = dict(os.environ, ROS_MASTER_URI=master_uri)
    results = tempfile.mkdtemp(prefix="bench_perception_loop_")
    launch_file = [a.launch_file] if a.launch_file else ["cottonsim_perception", "perception_demo.launch"]
    cmd = ["roslaunch", *launch_file,
           f"real_time_factor:={a.real_time_factor}", f"mask_source:={a.mask_source}",
           f"results_dir:={results}", *a.arg]
    log_path = os.path.join(results, "launch.log")
    started = []
    with open(log_path, "w") as log:
        # the master first (roslaunch gives up on one that takes long to start on a loaded machine)
        started.append(subprocess.Popen(["roscore", "-p", str(port)], env=env, stdout=log, stderr=subprocess.STDOUT,
                                        start_new_session=True))
        import rosgraph
        wall_end = time.monotonic() + 120.0
        while not rosgraph.is_master_online(master_uri) and time.monotonic() < wall_end:
            time.sleep(0.5)
        started.append(subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True))
    try:
        return measure(a, master_uri, log_path)
    finally:
        for proc in reversed(started):
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)


def measure(a, master_uri: str, log_path: str) -> int:
    os.environ["ROS_MASTER_URI"] = master_uri
    import rosgraph
    import rospy
    from rosgraph_msgs.msg import Clock
    from cottonsim_msgs.msg import SimStats

    wall_end = time.monotonic() + a.timeout_s
    while not rosgraph.is_master_online(master_uri):
        if time.monotonic() > wall_end:
            print(f"no ROS master at {master_uri}; see {log_path}", file=sys.stderr)
            return 2
        time.sleep(0.5)
    rospy.init_node("bench_perception_loop", anonymous=True, disable_signals=True)
    clock = {"t": 0.0}
    counts = {t: 0 for t in COUNTED_TOPICS}
    lock = threading.Lock()

    def on_clock(msg):
        clock["t"] = msg.clock.to_sec()

    def counter(topic):
        def cb(_msg):
            with lock:
                counts[topic] += 1
        return cb

    rospy.Subscriber("/clock", Clock, on_clock, queue_size=1)
    stats = {}
    rospy.Subscriber("/sim/stats", SimStats, lambda msg: stats.update(last=msg), queue_size=1)
    for topic in COUNTED_TOPICS:
        rospy.Subscriber(topic, rospy.AnyMsg, counter(topic), queue_size=50)

    def wait_sim(t_s):
        while clock["t"] < t_s:
            if time.monotonic() > wall_end:
                raise TimeoutError(f"sim time {clock['t']:.1f} s did not reach {t_s:.1f} s; see {log_path}")
            time.sleep(0.05)

    try:
        wait_sim(a.warmup_s)
        pids = node_pids(master_uri)
        cpu0 = {n: cpu_seconds(p) for n, p in pids.items()}
        sim0, wall0 = clock["t"], time.monotonic()
        with lock:
            counts0 = dict(counts)
        wait_sim(sim0 + a.window_s)
        sim1, wall1 = clock["t"], time.monotonic()
        cpu1 = {n: cpu_seconds(p) for n, p in pids.items() if os.path.exists(f"/proc/{p}")}
        with lock:
            counts1 = dict(counts)
    except TimeoutError as exc:
        print(f"bench_perception_loop: {exc}", file=sys.stderr)
        return 2
    sim_s, wall_s = sim1 - sim0, wall1 - wall0
    per_node = {n: (cpu1[n] - cpu0[n]) / sim_s for n in cpu1}
    perception = {n: v for n, v in per_node.items() if n.startswith(PERCEPTION_PREFIXES)}
    print(f"cpu count {os.cpu_count()}, load average {' '.join(f'{v:.1f}' for v in os.getloadavg())}; "
          f"window {sim_s:.1f} s sim in {wall_s:.1f} s wall: RTF {sim_s / wall_s:.2f}")
    print("CPU seconds per sim second:")
    for name, value in sorted(per_node.items(), key=lambda kv: -kv[1]):
        print(f"  {name:32s} {value:6.3f}")
    print(f"  {'perception nodes, sum':32s} {sum(perception.values()):6.3f}")
    print("outputs per sim second: " + ", ".join(f"{t} {(counts1[t] - counts0[t]) / sim_s:.2f}"
                                                for t in COUNTED_TOPICS))
    if "last" in stats:
        msg = stats["last"]
        print(f"simulator (/sim/stats): physics step {msg.physics_step_ms:.3f} ms; ms per update: " + ", ".join(
            f"{n} {v:.2f}" for n, v in sorted(zip(msg.sensor_names, msg.sensor_ms), key=lambda kv: -kv[1]) if v > 0))
    return 0


if __name__ == "__main__":
    sys.exit(main())
