"""rosrun cottonsim_experiments evaluate_bag on a small synthetic bag: the offline report matches hand-computed numbers."""
import json
import math
import subprocess

import pytest

import rosbag  # noqa: E402
import rospy  # noqa: E402
from cottonsim_msgs.msg import PlantContacts, SimStats  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from cottonsim_experiments.ros import bag_evaluation  # noqa: E402
from cottonsim_world.geodesy import HectorGeodesy  # noqa: E402


def make_bag(path, offset_m):
    """The robot drives lane 0 (world x = -1.43) from y = 5 to y = 25 at 0.5 m/s, offset_m to the east."""
    with rosbag.Bag(str(path), "w") as bag:
        def state(t, name):
            bag.write("/gps_waypoint_navigator/state", String(data=json.dumps({"state": name})), rospy.Time.from_sec(t))
        state(1.0, "waiting")
        state(2.0, "navigating")
        for k in range(0, 401):                   # 0.1 s steps, t = 2 .. 42 s
            t = 2.0 + 0.1 * k
            stamp = rospy.Time.from_sec(t)
            m = Odometry()
            m.header.stamp = stamp
            m.pose.pose.position.x = -1.43 + offset_m
            m.pose.pose.position.y = 5.0 + 0.05 * k
            m.pose.pose.orientation.z, m.pose.pose.orientation.w = math.sin(math.pi / 4), math.cos(math.pi / 4)
            bag.write("/ground_truth/odom", m, stamp)
            bag.write("/clock", Clock(clock=stamp), stamp)
            if k % 10 == 0:
                bag.write("/ground_truth/plant_contacts", PlantContacts(total_contact_events=3 + (k >= 200)), stamp)
                bag.write("/sim/stats", SimStats(sim_time=t, wall_time=2.0 * t), stamp)   # RTF 0.5
        state(42.0, "finished")


def test_offline_report(tmp_path):
    g = HectorGeodesy()
    route = tmp_path / "route.txt"
    pts = [(-1.43, 5.0), (-1.43, 15.0), (-1.43, 25.0)]
    with open(route, "w") as fh:
        for x, y in pts:
            lat, lon, _ = g.world_to_geodetic(x, y, 0.0)
            fh.write(f"{lat:.14f} {lon:.14f}\n")
    make_bag(tmp_path / "run.bag", 0.05)
    assert bag_evaluation.main([str(tmp_path / "run.bag"), "--waypoints", str(route), "--out", str(tmp_path / "out"),
                     "--no-plot"]) == 0
    r = json.loads((tmp_path / "out" / "report.json").read_text())
    assert r["complete"] is True and r["waypoints"] == 3 and r["cr_percent"] == 100.0
    assert r["ae_m"] == pytest.approx(0.05, abs=1e-3) and r["cr_percent_010m"] == 100.0
    assert r["plant_contacts"] == 1                       # 3 at the start, 4 at the end
    assert r["sim_duration_s"] == pytest.approx(40.0)     # "navigating" at 2 s .. "finished" at 42 s
    assert r["wall_duration_s"] == pytest.approx(80.0)    # from /sim/stats
    assert r["real_time_factor"] == pytest.approx(0.5)
    assert r["cross_track_mean_m"] == pytest.approx(0.05, abs=1e-3)   # lane 0 centre x = -1.43


def test_bad_inputs_exit_2(tmp_path, capsys):
    route = tmp_path / "route.txt"
    route.write_text("49.9 abc\n")
    assert bag_evaluation.main([str(tmp_path / "none.bag"), "--waypoints", str(route)]) == 2
    assert "route.txt:1" in capsys.readouterr().err
    route.write_text("49.9 8.9\n")
    assert bag_evaluation.main([str(tmp_path / "none.bag"), "--waypoints", str(route)]) == 2
    assert "bag not found" in capsys.readouterr().err


def test_the_command_reports_a_missing_bag_in_one_line(tmp_path):
    route = tmp_path / "route.txt"
    route.write_text("49.9 8.9\n")
    proc = subprocess.run(["rosrun", "cottonsim_experiments", "evaluate_bag", str(tmp_path / "none.bag"),
                           "--waypoints", str(route)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("evaluate_bag: bag not found")
