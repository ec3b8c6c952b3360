#!/usr/bin/env python3
"""Speed of the arm cores: UR5e IK per solve, collision checks, approach planning per boll, target fusion.

Run:  source scripts/env.sh && OMP_NUM_THREADS=1 python benchmarks/bench_manipulation.py
Prints medians (and p95 where it matters) of wall and CPU time of this process, the machine,
its load average and the commit. The approach scene: the robot's body from the committed URDF and
a row of three hand-built plants (a stem and ten branches each) 0.9 m to the robot's left, bolls
on their lane-facing halves, the arm starting from a stow pose over the robot.
"""
import argparse
import math
import os
import platform
import statistics
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for _pkg in ("cottonsim_common", "cottonsim_manipulation"):
    sys.path.insert(0, str(ROOT / "src" / _pkg / "src"))

from cottonsim_common.kinematics.ur5e import (  # noqa: E402
    UR5E_LOWER_LIMITS_RAD,
    UR5E_UPPER_LIMITS_RAD,
    forward_kinematics,
    inverse_kinematics,
    inverse_kinematics_batch,
    link_frames,
)
from cottonsim_manipulation.harvest.targets import BollDetection3D, TargetFusion  # noqa: E402
from cottonsim_manipulation.planning.approach import ApproachConfig, plan_approach  # noqa: E402
from cottonsim_common.capsules import CapsuleSet  # noqa: E402
from cottonsim_manipulation.planning.collision import ArmCollisionModel  # noqa: E402
from cottonsim_manipulation.planning.robot_body import body_boxes_from_urdf  # noqa: E402
from timing import wall_and_cpu_ms  # noqa: E402

GROUND_Z_M = -(0.13228 + 0.245 + 0.006)      # the ground in the arm's base frame
STOW_RAD = np.array([math.pi / 2, -2.2, 2.4, -1.77, -math.pi / 2, 0.0])


def machine():
    model = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                                text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "?"
    return f"{model}, {os.cpu_count()} CPUs; load average {os.getloadavg()[0]:.1f}; commit {commit}"


def timed(fn, repeats):
    """Median and p95 wall / CPU milliseconds of fn() (one warm-up call first)."""
    wall, cpu = wall_and_cpu_ms(fn, repeats)
    return statistics.median(wall), float(np.percentile(wall, 95)), statistics.median(cpu)


def plant(x_m, y_m, name):
    caps = [((x_m, y_m, GROUND_Z_M), (x_m, y_m, GROUND_Z_M + 0.93), 0.008, f"{name}/stem")]
    for k in range(10):
        h = GROUND_Z_M + 0.15 + 0.07 * k
        length = 0.1 + 0.2 * math.sin(math.pi * (k + 1) / 11)
        tip = (x_m + length * math.cos(2.4 * k), y_m + length * math.sin(2.4 * k), h + 0.05)
        caps.append(((x_m, y_m, h), tip, 0.004, f"{name}/branch{k}"))
    return caps


def bench_ik(rng, n):
    q = rng.uniform(UR5E_LOWER_LIMITS_RAD, UR5E_UPPER_LIMITS_RAD, (n, 6))
    poses = link_frames(q)[:, 6]
    it = iter(range(10 ** 9))

    def one():
        k = next(it) % n
        inverse_kinematics(poses[k], q[k])

    med, p95, cpu = timed(one, n)
    print(f"IK, one pose, all solutions sorted:   {med * 1e3:7.1f} us median, {p95 * 1e3:7.1f} us p95 "
          f"(cpu {cpu * 1e3:.1f} us)")
    med, _, cpu = timed(lambda: inverse_kinematics_batch(poses, q[0]), 5)
    print(f"IK, batch of {n} poses:               {med * 1e3 / n:7.2f} us per pose (cpu {cpu * 1e3 / n:.2f} us)")
    med, _, cpu = timed(lambda: forward_kinematics(q[0]), 200)
    print(f"FK, one configuration:                {med * 1e3:7.1f} us (cpu {cpu * 1e3:.1f} us)")


def bench_collision(model, plants, rng):
    q = rng.uniform(-math.pi, math.pi, (100, 6))
    med, _, cpu = timed(lambda: model.in_collision(q, plants), 20)
    print(f"collision check, 100 configurations:  {med:7.2f} ms (cpu {cpu:.2f} ms), "
          f"{len(plants)} plant capsules, {len(model.body)} body boxes")


def bench_approach(model, plants, repeats):
    """Per boll, the planner without approach yaw samples (the outward direction's vertical plane only)
    and with ApproachConfig's defaults, interleaved so that both see the same load. Two sets: the
    lane-facing halves (almost all planned) and bolls on the far halves facing away from the robot
    (none can be planned: every direction is tried)."""
    near, far = [], []
    for h in (0.35, 0.5, 0.65, 0.8, 0.95):
        for dy in (-0.2, 0.0, 0.2):
            for dx in (0.15, 0.25):
                near.append((np.array([0.9 - dx, dy, GROUND_Z_M + h]), np.array([-1.0, 0.5 * dy, 0.0])))
            far.append((np.array([1.1, dy, GROUND_Z_M + h]), np.array([1.0, 0.5 * dy, 0.0])))
    configs = {"yaw_samples_rad=(0.0,)": ApproachConfig(yaw_samples_rad=(0.0,)), "defaults": ApproachConfig()}
    for label, bolls in (("lane-facing", near), ("far halves", far)):
        times = {name: [] for name in configs}
        reasons = {name: Counter() for name in configs}
        durations = {name: [] for name in configs}
        for _ in range(repeats):
            for boll, outward in bolls:
                for name, config in configs.items():
                    t = time.perf_counter()
                    result = plan_approach(boll, outward, STOW_RAD, model, plants, config)
                    times[name].append((time.perf_counter() - t) * 1e3)
                    reasons[name][result.reason] += 1
                    if result.ok:
                        durations[name].append(result.plan.duration_s)
        for name in configs:
            motion = (f"; pick motion (transit + approach + retreat) {statistics.median(durations[name]):.2f} s median"
                      if durations[name] else "")
            print(f"approach plan per boll, {label}, {name} ({len(bolls)} bolls x {repeats}): "
                  f"{statistics.median(times[name]):7.1f} ms median, {np.percentile(times[name], 95):.1f} ms p95, "
                  f"{statistics.mean(times[name]):.1f} ms mean; {dict(reasons[name])}{motion}")


def bench_fusion(rng):
    truth = np.column_stack([rng.uniform(0, 20, 300), rng.uniform(0, 2, 300), rng.uniform(0.2, 1.0, 300)])
    fusion = TargetFusion()
    for k in range(30):                       # fill: every boll seen a few times
        fusion.update([BollDetection3D(p + rng.normal(0, 0.005, 3), 0.005) for p in truth[(k * 10) % 300:][:10]], k)
    frame = [BollDetection3D(p + rng.normal(0, 0.005, 3), 0.005) for p in truth[:12]]
    med, _, cpu = timed(lambda: fusion.update(frame, 100.0), 50)
    print(f"target fusion, 12 detections against {len(fusion)} targets: {med:.2f} ms (cpu {cpu:.2f} ms)")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ik-poses", type=int, default=2000, help="poses timed for IK (default 2000)")
    parser.add_argument("--only-approach", action="store_true", help="time the approach planning only")
    parser.add_argument("--repeats", type=int, default=2, help="rounds over the approach bolls (default 2)")
    args = parser.parse_args()
    print(f"machine: {machine()}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}")
    rng = np.random.default_rng(0)
    body = body_boxes_from_urdf((ROOT / "src/cottonsim_description/urdf/cottonsim_robot.urdf").read_text())
    model = ArmCollisionModel(body=body)
    plants = CapsuleSet.from_list(plant(0.9, -0.7, "p0") + plant(0.9, 0.0, "p1") + plant(0.9, 0.7, "p2"))
    if args.only_approach:
        bench_approach(model, plants, args.repeats)
        return
    bench_ik(rng, args.ik_poses)
    bench_collision(model, plants, rng)
    bench_approach(model, plants, args.repeats)
    bench_fusion(rng)


if __name__ == "__main__":
    main()
