"""Offline evaluator: the experiment report of a waypoint run from a recorded bag (``rosrun cottonsim_experiments evaluate_bag``).

Reads /ground_truth/odom, /ground_truth/plant_contacts, /clock, and when present
the navigator's state (start = first "navigating", end = "finished") and
/sim/stats (to recover the wall-clock duration), then writes the same files as
the experiment_recorder node (report.json, trajectory.csv, trajectory.png).

Example (a bag from `roslaunch cottonsim_experiments gps_navigation.launch record_bag:=true`):
  rosrun cottonsim_experiments evaluate_bag results/gps_run/run.bag --waypoints $(rospack find cottonsim_navigation)/config/waypoints/route_gps.txt \
      --out results/gps_run_offline
Map routes: --mode map (waypoints in the Home frame). A non-default farm: --sim-config FILE (sim.yaml shape).
Problems (missing bag or topic, bad waypoint file) print one line and exit with status 2.
"""
import argparse
import bisect
import json
import math
import os
import sys


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("bag", help="the recorded bag")
    ap.add_argument("--waypoints", required=True, help="the route file the navigator drove")
    ap.add_argument("--mode", choices=("gps", "map"), default="gps", help="route kind (default gps)")
    ap.add_argument("--out", help="output folder (default: <bag folder>/offline)")
    ap.add_argument("--run-name", default="", help="name written into the report")
    ap.add_argument("--sim-config", help="simulator settings YAML the run used (default: the built-in farm)")
    ap.add_argument("--home", type=float, nargs=3, metavar=("X", "Y", "YAW"),
                    help="world pose of the map frame for --mode map (default: the farm's spawn)")
    ap.add_argument("--state-topic", default=None,
                    help="the navigator's state topic (default: /gps_waypoint_navigator/state for --mode gps, "
                         "/map_waypoint_navigator/state for --mode map)")
    ap.add_argument("--record-period", type=float, default=0.05, help="spacing of kept poses [s of sim time]")
    ap.add_argument("--no-plot", action="store_true", help="skip trajectory.png")
    args = ap.parse_args(argv)
    if args.state_topic is None:
        args.state_topic = f"/{args.mode}_waypoint_navigator/state"

    import numpy as np
    from cottonsim_common.config.yaml_files import load_yaml_file
    from cottonsim_experiments.recording.experiment import (TrajectoryLog, TrajectoryLogConfig,
                                                            planned_world_from_gps, planned_world_from_map,
                                                            sim_world_from_settings, summary_line,
                                                            write_experiment)
    from cottonsim_navigation.waypoints.files import WaypointFileError, load_gps_waypoints, load_map_waypoints
    from cottonsim_common.pose import Pose2D

    def fail(text):
        print(f"evaluate_bag: {text}", file=sys.stderr)
        return 2

    settings = {}
    if args.sim_config:
        try:
            settings = load_yaml_file(args.sim_config, default={})
        except ValueError as exc:
            return fail(f"cannot read --sim-config {args.sim_config}: {exc}")
    try:
        world = sim_world_from_settings(settings)
        log = TrajectoryLog(TrajectoryLogConfig(min_period_s=args.record_period))
    except ValueError as exc:
        return fail(f"bad setting: {exc}")
    try:
        if args.mode == "gps":
            route = load_gps_waypoints(args.waypoints)
            planned_latlon = np.array([[w.lat, w.lon] for w in route], dtype=float)
            planned = planned_world_from_gps(route, world.geodesy)
        else:
            route = load_map_waypoints(args.waypoints)
            planned_latlon = None
            home = Pose2D(*args.home) if args.home else world.home
            planned = planned_world_from_map(route, home)
    except WaypointFileError as exc:
        return fail(f"bad waypoint file {exc}")
    if not os.path.isfile(args.bag):
        return fail(f"bag not found: {args.bag}")

    import rosbag
    from cottonsim_common.ros.conversions import yaw_from_quaternion_msg

    contacts_first = contacts_last = None
    start_s = end_s = None
    last_clock = None
    navigator = {}
    stats = []                                   # (sim s, wall s) from /sim/stats
    topics = ["/ground_truth/odom", "/ground_truth/plant_contacts", "/clock", "/sim/stats", args.state_topic]
    try:
        bag = rosbag.Bag(args.bag)
    except (rosbag.ROSBagException, OSError) as exc:
        return fail(f"cannot open bag {args.bag}: {exc}")
    with bag:
        for topic, msg, t in bag.read_messages(topics=topics):
            if topic == "/ground_truth/odom":
                p = msg.pose.pose
                log.add(msg.header.stamp.to_sec(), p.position.x, p.position.y, yaw_from_quaternion_msg(p.orientation))
            elif topic == "/ground_truth/plant_contacts":
                if contacts_first is None:
                    contacts_first = int(msg.total_contact_events)
                contacts_last = int(msg.total_contact_events)
            elif topic == "/clock":
                last_clock = msg.clock.to_sec()
            elif topic == "/sim/stats":
                if math.isfinite(msg.sim_time) and math.isfinite(msg.wall_time):
                    stats.append((float(msg.sim_time), float(msg.wall_time)))
            else:
                try:
                    state = json.loads(msg.data)
                except ValueError:
                    continue
                navigator = state
                name = state.get("state") if isinstance(state, dict) else None
                if name in ("navigating", "returning_home") and start_s is None:
                    start_s = t.to_sec()
                if name == "finished" and end_s is None:
                    end_s = t.to_sec()
    if len(log) == 0:
        return fail(f"no /ground_truth/odom messages in {args.bag}")
    traj = log.array
    complete = end_s is not None
    start_s = traj[0, 0] if start_s is None else start_s
    end_s = (last_clock if last_clock is not None else traj[-1, 0]) if end_s is None else end_s

    def wall_at(sim_s):
        """Wall time [s] at a sim time, interpolated along /sim/stats (None without stats)."""
        if len(stats) < 2:
            return None
        sims = [s for s, _ in stats]
        i = min(max(bisect.bisect_left(sims, sim_s), 1), len(stats) - 1)
        (s0, w0), (s1, w1) = stats[i - 1], stats[i]
        return w0 + (w1 - w0) * (sim_s - s0) / (s1 - s0) if s1 > s0 else w0

    w0, w1 = wall_at(start_s), wall_at(end_s)
    wall = max(0.0, w1 - w0) if w0 is not None and w1 is not None else 0.0
    out = args.out or os.path.join(os.path.dirname(os.path.abspath(args.bag)), "offline")
    report = write_experiment(out, args.mode, planned, traj, max(0.0, end_s - start_s), wall,
                              0 if contacts_first is None else contacts_last - contacts_first,
                              lanes=world.lanes, plant_xy=world.plant_xy, geodesy=world.geodesy,
                              planned_latlon=planned_latlon, complete=complete,
                              incomplete_reason="" if complete else "the bag holds no 'finished' navigator state",
                              run_name=args.run_name or os.path.splitext(os.path.basename(args.bag))[0],
                              waypoints_file=args.waypoints, navigator=navigator, plot=not args.no_plot)
    print(summary_line(report))
    print(f"wrote {out}")
    return 0
