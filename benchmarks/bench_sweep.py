#!/usr/bin/env python3
"""Scheduling overhead of `reproduce sweep` on a local Ray cluster: stub runs of a fixed length.

  python benchmarks/bench_sweep.py [--runs 12] [--run-s 2.0] [--cpus 2] [--cpus-per-run 1]

Each stub run sleeps --run-s seconds and returns a small report, so the sweep's wall time minus the
ideal (runs x run length / runs at a time) is what the engine adds: task submission, the outcome's
trip back, writing the run folder and the tables. Printed: cluster start [s], sweep wall [s], ideal
[s], overhead per run [s] and as a share of a short real run (--short-run-s, the 3-waypoint route).
"""
import argparse
import json
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src", "cottonsim_experiments",
                                "src"))

from cottonsim_experiments.sweep.engine import EngineConfig, run_sweep  # noqa: E402
from cottonsim_experiments.sweep.spec import parse_sweep  # noqa: E402


def sleep_run(run, cpus, run_s=2.0):
    time.sleep(run_s)
    return {"status": "done", "wall_s": run_s,
            "files": {"report.json": json.dumps({"complete": True, "cr_percent": 100.0, "ae_m": 0.05})}}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=12)
    ap.add_argument("--run-s", type=float, default=2.0)
    ap.add_argument("--cpus", type=int, default=2)
    ap.add_argument("--cpus-per-run", type=int, default=1)
    ap.add_argument("--short-run-s", type=float, default=16.0,
                    help="wall time of a short real run to compare with (the 3-waypoint GPS route, quiet machine)")
    a = ap.parse_args()
    import functools

    import ray

    t0 = time.monotonic()
    ray.init(num_cpus=a.cpus, include_dashboard=False, log_to_driver=False)
    start_s = time.monotonic() - t0
    spec = parse_sweep({"name": "bench", "experiment": "gps_route", "seeds": list(range(a.runs))})
    run_function = functools.partial(sleep_run, run_s=a.run_s)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.monotonic()
        run_sweep(spec, tmp, EngineConfig(cpus_per_run=a.cpus_per_run, progress_interval_s=60.0), run_function,
                  log=lambda s: None)
        wall_s = time.monotonic() - t0
    ray.shutdown()
    slots = a.cpus // a.cpus_per_run
    ideal_s = a.run_s * -(-a.runs // slots)
    per_run_s = (wall_s - ideal_s) / a.runs
    print(f"cluster start {start_s:.2f} s; {a.runs} runs of {a.run_s:.1f} s, {slots} at a time: wall {wall_s:.2f} s, "
          f"ideal {ideal_s:.2f} s; overhead {per_run_s:.3f} s per run = "
          f"{100.0 * per_run_s / a.short_run_s:.2f} % of a {a.short_run_s:.0f} s short run")
    return 0


if __name__ == "__main__":
    sys.exit(main())
