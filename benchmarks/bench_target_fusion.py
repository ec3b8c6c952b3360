#!/usr/bin/env python3
"""Boll target fusion (harvest.targets.TargetFusion): milliseconds per update on a long run.

A robot drives 40 m along two rows of bolls (1500 bolls at +-0.9 m, 0.2-1.0 m high) and sees
every boll within 1.5 m of it, 2 mm noise, 20 frames per metre (the ground-truth harvest mode at
20 Hz and 1 m/s); the field fills with targets, and the last --frames updates are timed.

  python benchmarks/bench_target_fusion.py [--bolls 1500] [--frames 300] [--repeats 3]

Compare two trees by running this script with each tree's scripts/env.sh sourced.
"""
import argparse
import time

import numpy as np

from cottonsim_manipulation.harvest.targets import BollDetection3D, TargetFusion, TargetFusionConfig


def run(bolls: int, frames: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    field = np.c_[rng.uniform(0.0, 40.0, bolls), rng.choice([-0.9, 0.9], bolls) + rng.normal(0.0, 0.1, bolls),
                  rng.uniform(0.2, 1.0, bolls)]
    fusion = TargetFusion(TargetFusionConfig(track_observations=20))
    total_frames = 800
    elapsed = 0.0
    for k in range(total_frames):
        x = k * 0.05
        seen = field[np.abs(field[:, 0] - x) < 1.5]
        detections = [BollDetection3D(p + rng.normal(0.0, 0.002, 3), 0.002) for p in seen]
        start = time.perf_counter()
        fusion.update(detections, k * 0.05)
        if k >= total_frames - frames:
            elapsed += time.perf_counter() - start
    return len(fusion), 1000.0 * elapsed / frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bolls", type=int, default=1500)
    parser.add_argument("--frames", type=int, default=300, help="updates timed at the end of the run")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    if not (1 <= args.frames <= 800):
        parser.error("--frames must be in [1, 800]")
    for r in range(args.repeats):
        targets, ms = run(args.bolls, args.frames, seed=r)
        print(f"run {r}: {targets} targets, {ms:.1f} ms per update (last {args.frames} of 800 frames)")


if __name__ == "__main__":
    main()
