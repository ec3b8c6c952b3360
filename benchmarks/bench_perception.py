#!/usr/bin/env python3
"""Speed of the Cotton-Eye networks on the CPU: ms per 640x480 frame, params, GFLOPs.

Measures Predictor.predict (letterbox + network + post-processing + masks
mapped back to 640x480) for the scene segmenter and the boll detector, with
randomly initialised weights of the default (or given) configuration, at 1 and
2 torch threads. A random-weights network with conf_threshold 0.25 yields few
boxes, so mask post-processing of a trained model (a handful of instances)
adds a little; the network forward time is printed separately.

  python benchmarks/bench_perception.py [--frames 30] [--seg-width 0.125] [--det-width 0.25]
"""
import argparse
import os
import sys
import tempfile
import time

import numpy as np
import torch

from cottonsim_perception.inference import Predictor
from cottonsim_perception.nn.models import ModelConfig, build_model, count_parameters, save_checkpoint


def gflops(model: torch.nn.Module, height: int, width: int) -> float:
    """Multiply-adds x 2 of all Conv2d / ConvTranspose2d layers for one image [GFLOPs]."""
    total = [0]

    def hook(mod, inp, out):
        k = mod.kernel_size[0] * mod.kernel_size[1]
        cin = mod.in_channels // mod.groups
        total[0] += 2 * out.numel() * cin * k

    hs = [m.register_forward_hook(hook) for m in model.modules()
          if isinstance(m, (torch.nn.Conv2d, torch.nn.ConvTranspose2d))]
    with torch.no_grad():
        model.eval()(torch.zeros(1, 3, height, width))
    for h in hs:
        h.remove()
    return total[0] / 1e9


def time_it(fn, frames: int) -> float:
    for _ in range(3):
        fn()
    t = time.perf_counter()
    for _ in range(frames):
        fn()
    return (time.perf_counter() - t) / frames * 1000.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--seg-width", type=float, default=None)
    ap.add_argument("--det-width", type=float, default=None)
    ap.add_argument("--seg-imgsz", default=None, help="WxH")
    ap.add_argument("--det-imgsz", default=None, help="WxH")
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 255, (480, 640, 3), dtype=np.uint8)
    configs = []
    for task, width, imgsz in (("seg", a.seg_width, a.seg_imgsz), ("det", a.det_width, a.det_imgsz)):
        over = {}
        if width:
            over["width_multiple"] = width
        if imgsz:
            w, h = (int(v) for v in imgsz.lower().split("x"))
            over.update(input_width=w, input_height=h)
        configs.append(ModelConfig.scene_segmenter(**over) if task == "seg" else ModelConfig.boll_detector(**over))
    print(f"torch {torch.__version__}, cpu count {os.cpu_count()}, frame 640x480, {a.frames} frames")
    with tempfile.TemporaryDirectory() as d:
        for cfg in configs:
            torch.manual_seed(0)
            model = build_model(cfg).eval()
            path = os.path.join(d, f"{cfg.task}.pt")
            save_checkpoint(path, model)
            print(f"\n{cfg.task}: input {cfg.input_width}x{cfg.input_height}, width {cfg.width_multiple}, "
                  f"depth {cfg.depth_multiple}, params {count_parameters(model) / 1e6:.3f} M, "
                  f"{gflops(model, cfg.input_height, cfg.input_width):.2f} GFLOPs")
            for threads in (1, 2):
                p = Predictor(path, conf_threshold=0.25, threads=threads)
                x = torch.rand(1, 3, cfg.input_height, cfg.input_width)
                with torch.inference_mode():
                    net_ms = time_it(lambda: p.model(x), a.frames)
                total_ms = time_it(lambda: p.predict(frame), a.frames)
                print(f"  threads {threads}: predict {total_ms:6.1f} ms/frame (network {net_ms:6.1f} ms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
