#!/usr/bin/env python3
"""Real-time factor of the whole simulator core (no ROS), per sensor set.

Profiles (the issue's two aims):
  all   - every sensor at the paper's rates: 3 cameras 640x480 at 30 Hz (+ point clouds),
          VLP-16 at 10 Hz, IMU 50 Hz, GPS 40 Hz, odometry 50 Hz
  nav   - navigation sensors only: front camera 320x240 at 10 Hz, VLP-16 10 Hz, IMU, GPS
  none  - physics, IMU, GPS and odometry only

Where the robot is (--places; the sensors' cost depends on it):
  headland - from the spawn pose ("Home", world (-6.0, 1.0), facing the rows 8 m ahead) the robot
             drives an arc (0.5 m/s, 0.15 rad/s) through the headland;
  lane     - the robot is spawned inside lane 3 (world x = -6.83, y = 10.0, facing +y: a row of
             plants 0.9 m to each side, 12 m of lane ahead) and drives straight along it at 0.5 m/s.
Prints sim seconds, wall and CPU seconds (all threads, and the main thread's), the real-time factor and ms per update of each sensor
(wall, and process CPU summed over threads: on a loaded machine, NUMBA_NUM_THREADS=1 and the CPU
figures are the load-independent measure of the work).

  OMP_NUM_THREADS=2 python benchmarks/bench_sim.py [--profiles all,nav,none] [--places headland,lane] [--seconds 5]
      [--sensor-workers N]

--job-breakdown (with --sensor-workers) splits the sensor jobs' wall time into CPU, run-queue
wait (no free core) and blocked (the GIL), from the worker thread's /proc schedstat. With
NUMBA_NUM_THREADS > 1 "blocked" also holds the worker's waits for numba's own threads at the end
of each parallel kernel: read it as the GIL with NUMBA_NUM_THREADS=1 only.

--compare-workers N steps a serial and an N-worker simulator of each profile in one
process, in alternating segments (--segments per mode), and prints both RTFs and the
speed-up per pair: a comparison that a loaded machine's slow drift hits alike.

--sensor-workers N runs cameras and LiDAR on N threads beside the physics
(SimulatorConfig.sensor_workers; 0 = serial, the default); the timed run
then ends with the pending readings collected. Per-update figures of those
sensors are then the worker thread's own (numba's helper threads not in the CPU column).

On a shared machine wall time is noisy; instruction counts are not. --callgrind
switches callgrind's instrumentation on for the timed loop only (start-up and
warm-up excluded), so the count per simulated second can be read off:

  valgrind --tool=callgrind --instr-atstart=no python benchmarks/bench_sim.py \
      --profiles none --seconds 1 --callgrind        # "Collected : N" = instructions
"""
import argparse
import dataclasses
import math
import os
import pathlib
import platform
import statistics
import subprocess
import threading
import time
from concurrent.futures import wait as futures_wait

from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.farm.model import Pose2D
from cottonsim_world.robot.urdf_model import UrdfModel
from cottonsim_world.simulator import Simulator

ROOT = pathlib.Path(__file__).resolve().parents[1]
URDF = ROOT / "src/cottonsim_description/urdf/cottonsim_robot.urdf"
OFF = {"enabled": False}
PROFILES = {
    "all": {"cameras": {c: {"width": 640, "height": 480, "rate_hz": 30.0}
                        for c in ("realsense_p", "realsense_secondary", "realsense_tertiary")}},
    "nav": {"cameras": {"realsense_p": {"width": 320, "height": 240, "rate_hz": 10.0},
                        "realsense_secondary": OFF, "realsense_tertiary": OFF}},
    "none": {"cameras": {"realsense_p": OFF, "realsense_secondary": OFF, "realsense_tertiary": OFF},
             "lidar_enabled": False},
}


PLACES = ("headland", "lane")
LANE_INDEX, LANE_START_Y_M = 3, 10.0


def _place(config, place: str):
    """The farm with the robot spawned where ``place`` says, and the (v [m/s], w [rad/s]) it drives."""
    farm = generate_farm(config.farm)
    if place == "headland":
        return farm, (0.5, 0.15)
    lane = farm.lanes[LANE_INDEX]
    return dataclasses.replace(farm, spawn=Pose2D(lane.x_m, LANE_START_Y_M, math.pi / 2)), (0.5, 0.0)


def _callgrind(switch: str) -> None:
    """Turn callgrind's instrumentation of this process on or off (no-op outside valgrind)."""
    subprocess.run(["callgrind_control", "-i", switch, str(os.getpid())], stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, check=False)


def _thread_schedstat():
    """(CPU [s], time runnable but waiting for a core [s]) of the calling thread (Linux schedstat)."""
    with open(f"/proc/self/task/{threading.get_native_id()}/schedstat") as f:
        cpu_ns, wait_ns, _slices = f.read().split()
    return int(cpu_ns) * 1e-9, int(wait_ns) * 1e-9


class JobBreakdown:
    """Splits each pipelined sensor job's wall time into CPU, run-queue wait and the rest (blocked:
    the GIL), from the worker thread's schedstat at the job's start and end; wraps the simulator
    module's job runner while installed (a benchmark probe, Linux only)."""

    def __init__(self):
        import cottonsim_world.simulator as simulator_module
        self._module = simulator_module
        self._original = simulator_module.timed_job
        self.sums = {}                   # job function name -> [jobs, wall, cpu, run queue] [s]

        def timed(after, produce, *args):
            if after is not None:        # the wait for the sensor's previous job is not the job's
                futures_wait((after,))
            t0, (c0, q0) = time.perf_counter(), _thread_schedstat()
            result = self._original(None, produce, *args)
            (c1, q1), t1 = _thread_schedstat(), time.perf_counter()
            entry = self.sums.setdefault(produce.__name__.lstrip("_"), [0, 0.0, 0.0, 0.0])
            entry[0] += 1
            entry[1] += t1 - t0
            entry[2] += c1 - c0
            entry[3] += q1 - q0
            return result

        simulator_module.timed_job = timed

    def remove(self):
        self._module.timed_job = self._original


def run(profile: str, seconds: float, clouds: bool, callgrind: bool = False, place: str = "headland",
        sensor_workers: int = 0, switch_interval_s=None, breakdown: bool = False):
    sim, (v_m_s, w_rad_s) = _make_sim(profile, place, clouds, sensor_workers, switch_interval_s)
    probe = JobBreakdown() if breakdown and sensor_workers else None
    if callgrind:
        _callgrind("on")
    wait0 = getattr(sim, "sensor_wait_s", 0.0)
    t0_sim, t0, c0, m0 = sim.time_s, time.perf_counter(), time.process_time(), time.thread_time()
    while sim.time_s - t0_sim < seconds - 1e-9:
        sim.command_velocity(v_m_s, w_rad_s)
        sim.step()
    if hasattr(sim, "flush_readings"):     # pipelined: the readings still pending belong to the timed run
        sim.flush_readings()
    wall, cpu, main_cpu = time.perf_counter() - t0, time.process_time() - c0, time.thread_time() - m0
    if callgrind:
        _callgrind("off")
    sim_s = sim.time_s - t0_sim
    # (older trees lack sensor_cpu_ms; kept optional so that before/after runs use the same script)
    cpu_ms = sim.sensor_cpu_ms() if hasattr(sim, "sensor_cpu_ms") else {}
    timing = {k: (v, cpu_ms.get(k, float("nan"))) for k, v in sim.sensor_timing_ms().items() if v > 0}
    sim.close()
    waited = getattr(sim, "sensor_wait_s", 0.0) - wait0
    notes = []
    if probe is not None:
        probe.remove()
        for name, (jobs, job_wall, job_cpu, queued) in probe.sums.items():
            notes.append(f"  {name} jobs: {jobs}, wall {job_wall:.3f} s = CPU {job_cpu:.3f} + run queue {queued:.3f} "
                         f"+ blocked (GIL) {job_wall - job_cpu - queued:.3f}; "
                         f"{job_wall / max(wall, 1e-9):.0%} of the run's wall time")
    return sim_s, wall, cpu, timing, sim.physics_step_ms(), sim.step_s, main_cpu, waited, notes


def _make_sim(profile: str, place: str, clouds: bool, sensor_workers: int, switch_interval_s=None):
    """A warmed-up simulator of ``profile`` at ``place`` and the command it drives with."""
    settings = dict(PROFILES[profile])
    if sensor_workers:                     # (older trees lack the key: serial runs leave it out)
        settings["sensor_workers"] = sensor_workers
    if switch_interval_s is not None:
        settings["sensor_switch_interval_s"] = switch_interval_s
    config = simulator_config_from_dict(settings)
    farm, command = _place(config, place)
    sim = Simulator(config, UrdfModel.from_file(URDF), farm=farm)
    for cam in sim.cameras:
        sim.set_camera_cloud_wanted(cam, clouds and profile == "all")
    sim.step_for(0.2)                      # warm-up (first renders, JIT)
    if hasattr(sim, "flush_readings"):
        sim.flush_readings()
    return sim, command


def compare_workers(profile: str, place: str, seconds: float, clouds: bool, workers: int, segments: int,
                    switch_interval_s=None):
    """Serial and ``workers``-pipelined simulators in one process, stepped in alternating segments.

    Each takes ``segments`` segments of seconds / segments sim seconds, in the order
    serial, pipelined, pipelined, serial, ... so that a slow drift of the machine's load
    hits both alike. Returns the wall times [s] of the segments per mode.
    """
    sims = {w: _make_sim(profile, place, clouds, w, switch_interval_s) for w in (0, workers)}
    seg_s = seconds / segments
    walls = {0: [], workers: []}
    for i in range(segments):
        for w in ((0, workers) if i % 2 == 0 else (workers, 0)):
            sim, (v_m_s, w_rad_s) = sims[w]
            t0, s0 = time.perf_counter(), sim.time_s
            while sim.time_s - s0 < seg_s - 1e-9:
                sim.command_velocity(v_m_s, w_rad_s)
                sim.step()
            sim.flush_readings()
            walls[w].append(time.perf_counter() - t0)
    for sim, _ in sims.values():
        sim.close()
    return seg_s, walls


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profiles", default="all,nav,none")
    parser.add_argument("--places", default="headland,lane", help=f"where the robot drives, of {PLACES}")
    parser.add_argument("--seconds", type=float, default=5.0, help="sim seconds per profile")
    parser.add_argument("--no-clouds", action="store_true", help="skip the cameras' point clouds")
    parser.add_argument("--sensor-workers", type=int, default=0,
                        help="SimulatorConfig.sensor_workers: threads that run cameras and LiDAR beside the "
                             "physics (0 = serial)")
    parser.add_argument("--switch-interval-s", type=float, default=None,
                        help="SimulatorConfig.sensor_switch_interval_s for the pipelined runs (default: the config's)")
    parser.add_argument("--job-breakdown", action="store_true",
                        help="with --sensor-workers: split the jobs' wall time into CPU, run-queue wait and "
                             "blocked (the GIL), from the worker's /proc schedstat (Linux)")
    parser.add_argument("--compare-workers", type=int, default=0, metavar="N",
                        help="instead: step a serial and an N-worker simulator in one process in alternating "
                             "segments and print both real-time factors and the speed-up per pair")
    parser.add_argument("--segments", type=int, default=12, help="segments per mode for --compare-workers")
    parser.add_argument("--callgrind", action="store_true",
                        help="under valgrind --tool=callgrind --instr-atstart=no: instrument the timed loop only")
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}, "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS', 'unset')}; sensor workers {args.sensor_workers}")
    places = args.places.split(",")
    for place in places:
        if place not in PLACES:
            parser.error(f"--places: unknown place {place!r}, known: {PLACES}")
    for profile in args.profiles.split(","):
        if profile not in PROFILES:
            parser.error(f"--profiles: unknown profile {profile!r}, known: {sorted(PROFILES)}")
    if args.compare_workers:
        for place in places:
            for profile in args.profiles.split(","):
                seg_s, walls = compare_workers(profile, place, args.seconds, not args.no_clouds,
                                               args.compare_workers, args.segments, args.switch_interval_s)
                print(f"\n[{profile} @ {place}] {args.segments} x {seg_s:.2f} sim s per mode, alternating")
                for w, label in ((0, "serial"), (args.compare_workers, f"{args.compare_workers} sensor workers")):
                    rtf = sorted(seg_s / x for x in walls[w])
                    print(f"  {label:17s} real-time factor {seg_s * len(walls[w]) / sum(walls[w]):.2f} "
                          f"(segments: median {statistics.median(rtf):.2f}, range {rtf[0]:.2f}-{rtf[-1]:.2f})")
                gain = sorted(a / b for a, b in zip(walls[0], walls[args.compare_workers]))
                print(f"  speed-up per pair: median {statistics.median(gain):.2f}, range {gain[0]:.2f}-{gain[-1]:.2f}; "
                      f"load average now {os.getloadavg()[0]:.1f}")
        return
    for place in places:
        for profile in args.profiles.split(","):
            sim_s, wall, cpu, timing, physics_ms, step_s, main_cpu, waited, notes = run(
                profile, args.seconds, not args.no_clouds, args.callgrind, place, args.sensor_workers,
                args.switch_interval_s, args.job_breakdown)
            print(f"\n[{profile} @ {place}] {sim_s:.1f} sim s in {wall:.2f} wall s ({cpu:.2f} cpu s, "
                  f"{main_cpu:.2f} of them in the main thread): "
                  f"real-time factor {sim_s / wall:.2f} (cpu {sim_s / cpu:.2f})")
            print(f"  physics step {physics_ms:.3f} ms (step {step_s * 1e3:.1f} ms)"
                  + (f"; main thread waited {waited:.2f} s for the sensor workers" if args.sensor_workers else ""))
            for line in notes:
                print(line)
            for name, (ms, cpu_ms) in timing.items():
                print(f"  {name:22s} {ms:8.2f} ms per update (cpu {cpu_ms:.2f} ms)")

if __name__ == "__main__":
    main()
