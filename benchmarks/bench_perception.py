#!/usr/bin/env python3
"""Speed of the Cotton-Eye networks on the CPU: ms per 640x480 frame, params, GFLOPs.

Measures the whole per-frame work of the perception nodes:
Predictor.predict (letterbox + network + post-processing + masks mapped back
to 640x480) and, for the segmenter, the label image the row-centring node
reads (localization.label_image_from_detections), for the scene segmenter
and the boll detector at 1 and 2 torch threads. By default the weights the
nodes run (src/cottonsim_perception/weights/: scene_segmenter.pt and
boll_detector_sim.pt; --det-weights boll_detector.pt times the paper-domain
detector, 960x736 input) run on real frames (the paper's
Segmentation / Detection valid images, cycled), so post-processing handles
the instances a trained model really outputs; --random-weights measures an
untrained network of the default (or given) configuration instead.

By default the networks run as the nodes run them (Predictor's frozen
channels-last TorchScript graph, ``nn.optimize``); --eager times the fused
eager model instead (the state before that optimisation), for comparison.

Printed per case: median and 10th percentile wall ms per frame (the median is
what a node sees; the 10th percentile approximates an unloaded machine), and
CPU ms per frame (process time of all threads: on a shared machine the
least load-sensitive figure; with 2 threads it is the sum over both).

--compare runs the eager and the frozen predictor of the same weights in
alternation (rounds of 5 frames each) and prints, per variant, the lowest CPU
ms per frame over the rounds: on a shared machine the fairest A/B figure.

  python benchmarks/bench_perception.py [--frames 40] [--random-weights] [--only seg|det] [--eager]
  python benchmarks/bench_perception.py --compare [--rounds 10] [--only seg]
  python benchmarks/bench_perception.py --compare --only seg --seg-weights-b OTHER.pt

With --seg-weights-b, --compare runs the frozen predictors of --seg-weights
and of those weights in alternation instead (A/B of two segmenter
architectures, e.g. proto_stride 2 vs 1, on the same frames and load).

--compare-backends runs the torch backend (frozen graph) and the onnxruntime
backend (the .onnx export beside the weights, what the nodes run) in
alternation the same way; for the detector also onnxruntime on both side
cameras' frames as one batch of 2 (the boll_detection node), per frame:

  python benchmarks/bench_perception.py --compare-backends [--rounds 10] [--threads 1]
"""
import argparse
import glob
import os
import sys
import tempfile
import time

import cv2
import numpy as np
import torch

from cottonsim_perception.inference import Predictor
from cottonsim_perception.localization import label_image_from_detections
from cottonsim_perception.nn.models import ModelConfig, build_model, count_parameters, save_checkpoint

HERE = os.path.dirname(os.path.abspath(__file__))
WEIGHTS = os.path.join(HERE, "..", "src", "cottonsim_perception", "weights")
# the paper's labelled images (Segmentation/, Detection/): --seg-images / --det-images or $COTTONSIM_PAPER_DATA
ORIGINAL = os.environ.get("COTTONSIM_PAPER_DATA", "")


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


def time_frames(fn, frames, n: int):
    """(median wall ms, 10th-percentile wall ms, CPU ms) per call over n calls, cycling frames."""
    for i in range(3):
        fn(frames[i % len(frames)])
    walls = []
    c0 = time.process_time()
    for i in range(n):
        t = time.perf_counter()
        fn(frames[i % len(frames)])
        walls.append(time.perf_counter() - t)
    cpu = (time.process_time() - c0) / n
    w = np.array(walls) * 1e3
    return float(np.median(w)), float(np.percentile(w, 10)), cpu * 1e3


def compare_cpu(variants, frames, rounds: int, per_round: int = 5):
    """Lowest CPU ms per call over interleaved rounds, per variant (name -> fn(frame))."""
    best = {k: float("inf") for k in variants}
    for fn in variants.values():
        for i in range(3):
            fn(frames[i % len(frames)])
    for r in range(rounds):
        for name, fn in variants.items():
            c0 = time.process_time()
            for i in range(per_round):
                fn(frames[(r * per_round + i) % len(frames)])
            best[name] = min(best[name], (time.process_time() - c0) / per_round * 1e3)
    return best


def backend_variants(task: str, path: str, threads: int):
    """name -> fn(frame) doing a node's whole work per frame on each backend (det: also a batch of 2, per frame)."""
    preds = {b: Predictor(path, threads=threads, backend=b) for b in ("torch", "onnxruntime")}
    if task == "seg":
        return {b: (lambda f, p=p: label_image_from_detections(p.predict(f), f.shape[:2])) for b, p in preds.items()}
    variants = {b: p.predict for b, p in preds.items()}
    batch = preds["onnxruntime"]
    # one call handles two frames; it runs every other call, so its CPU per call is per frame
    pending = []

    def both_cameras(frame):
        pending.append(frame)
        if len(pending) == 2:
            batch.predict_batch(pending)
            pending.clear()

    variants["onnxruntime, batch of 2"] = both_cameras
    return variants


def load_frames(folder: str, count: int = 8):
    """Up to ``count`` RGB frames of a folder resized to 640x480, or one noise frame if none."""
    paths = sorted(glob.glob(os.path.join(folder, "*.jpg")) + glob.glob(os.path.join(folder, "*.png")))[:count]
    frames = []
    for p in paths:
        bgr = cv2.imread(p, cv2.IMREAD_COLOR)
        if bgr is not None:
            frames.append(cv2.cvtColor(cv2.resize(bgr, (640, 480)), cv2.COLOR_BGR2RGB))
    if not frames:
        frames = [np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)]
    return frames, (folder if paths else "random noise")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=40, help="timed frames per case (default 40)")
    ap.add_argument("--only", choices=("seg", "det"), default=None)
    ap.add_argument("--random-weights", action="store_true", help="untrained networks of the presets")
    ap.add_argument("--eager", action="store_true", help="fused eager model instead of the frozen graph")
    ap.add_argument("--compare", action="store_true", help="interleaved eager vs frozen CPU time per frame")
    ap.add_argument("--compare-backends", action="store_true",
                    help="interleaved torch vs onnxruntime CPU time per frame (and a batch of 2 for det)")
    ap.add_argument("--rounds", type=int, default=10, help="with --compare: rounds of 5 frames (default 10)")
    ap.add_argument("--threads", default="1,2", help="torch thread counts to time, comma-separated (default 1,2)")
    ap.add_argument("--seg-weights", default=os.path.join(WEIGHTS, "scene_segmenter.pt"))
    ap.add_argument("--det-weights", default=os.path.join(WEIGHTS, "boll_detector_sim.pt"),
                    help="boll detector (default: boll_detector_sim.pt, the one perception.launch runs)")
    ap.add_argument("--seg-weights-b", default=None,
                    help="with --compare: frozen --seg-weights vs frozen these weights (A/B of two segmenters)")
    ap.add_argument("--seg-images", default=os.path.join(ORIGINAL, "Segmentation", "valid", "images"))
    ap.add_argument("--det-images", default=os.path.join(ORIGINAL, "Detection", "valid", "images"))
    ap.add_argument("--seg-width", type=float, default=None, help="with --random-weights")
    ap.add_argument("--det-width", type=float, default=None, help="with --random-weights")
    ap.add_argument("--seg-imgsz", default=None, help="WxH, with --random-weights")
    ap.add_argument("--det-imgsz", default=None, help="WxH, with --random-weights")
    a = ap.parse_args()
    if a.frames < 1:
        ap.error("--frames must be >= 1")
    if a.rounds < 1:
        ap.error("--rounds must be >= 1")
    tasks = [t for t in ("seg", "det") if a.only in (None, t)]
    try:
        thread_counts = [int(v) for v in a.threads.split(",")]
    except ValueError:
        ap.error(f"--threads must be comma-separated ints, got {a.threads!r}")
    if not thread_counts or min(thread_counts) < 1:
        ap.error("--threads needs positive thread counts")
    print(f"torch {torch.__version__}, cpu count {os.cpu_count()}, load average "
          f"{' '.join(f'{v:.1f}' for v in os.getloadavg())}, frame 640x480, {a.frames} frames per case")
    with tempfile.TemporaryDirectory() as d:
        for task in tasks:
            if a.random_weights:
                width, imgsz = (a.seg_width, a.seg_imgsz) if task == "seg" else (a.det_width, a.det_imgsz)
                over = {"width_multiple": width} if width else {}
                if imgsz:
                    w, h = (int(v) for v in imgsz.lower().split("x"))
                    over.update(input_width=w, input_height=h)
                cfg = ModelConfig.scene_segmenter(**over) if task == "seg" else ModelConfig.boll_detector(**over)
                torch.manual_seed(0)
                path = os.path.join(d, f"{task}.pt")
                save_checkpoint(path, build_model(cfg).eval())
            else:
                path = a.seg_weights if task == "seg" else a.det_weights
                if not os.path.isfile(path):
                    print(f"{task}: weights {path} not found (use --random-weights)", file=sys.stderr)
                    return 2
            frames, source = load_frames(a.seg_images if task == "seg" else a.det_images)
            if a.compare_backends:
                for threads in thread_counts:
                    # rounds of 6 frames: the batch variant runs 3 whole batches per round
                    best = compare_cpu(backend_variants(task, path, threads), frames, a.rounds, per_round=6)
                    print(f"{task} ({os.path.basename(path)}), threads {threads}: lowest CPU ms per frame over "
                          f"{a.rounds} interleaved rounds ({source}): "
                          + ", ".join(f"{k} {v:.1f}" for k, v in best.items()))
                continue
            if a.compare:
                for threads in thread_counts:
                    if task == "seg" and a.seg_weights_b:
                        preds = {os.path.basename(q): Predictor(q, threads=threads, optimize=True)
                                 for q in (path, a.seg_weights_b)}
                    else:
                        preds = {"eager": Predictor(path, threads=threads, optimize=False),
                                 "frozen": Predictor(path, threads=threads, optimize=True)}
                    variants = {}
                    for name, p in preds.items():
                        if task == "seg":
                            variants[name] = (lambda f, p=p: label_image_from_detections(p.predict(f), f.shape[:2]))
                        else:
                            variants[name] = preds[name].predict
                    best = compare_cpu(variants, frames, a.rounds)
                    print(f"{task} ({os.path.basename(path)}), threads {threads}: lowest CPU ms per frame over "
                          f"{a.rounds} interleaved rounds: " + ", ".join(f"{k} {v:.1f}" for k, v in best.items()))
                continue
            for threads in thread_counts:
                p = Predictor(path, conf_threshold=0.25, threads=threads, optimize=not a.eager)
                cfg = p.config
                if threads == thread_counts[0]:
                    print(f"\n{task}: {os.path.basename(path)}, input {cfg.input_width}x{cfg.input_height}, "
                          f"width {cfg.width_multiple}, params {count_parameters(p.model) / 1e6:.3f} M, "
                          f"{gflops(p.model, cfg.input_height, cfg.input_width):.2f} GFLOPs, "
                          f"{'frozen TorchScript, channels-last' if p.optimized else 'eager'}; "
                          f"frames: {source} ({len(frames)})")
                x = [torch.rand(1, 3, cfg.input_height, cfg.input_width)]
                if p.optimized:
                    x = [x[0].contiguous(memory_format=torch.channels_last)]
                net = time_frames(p.network, x, a.frames)
                if task == "seg":
                    def work(f):
                        return label_image_from_detections(p.predict(f), f.shape[:2])
                else:
                    work = p.predict
                tot = time_frames(work, frames, a.frames)
                n_inst = np.mean([len(p.predict(f)) for f in frames])
                print(f"  threads {threads}: per frame {tot[0]:6.1f} ms median, {tot[1]:6.1f} ms p10, "
                      f"{tot[2]:6.1f} ms CPU | network only {net[0]:6.1f} ms median, {net[1]:6.1f} ms p10, "
                      f"{net[2]:6.1f} ms CPU | {n_inst:.1f} instances/frame")
    return 0


if __name__ == "__main__":
    sys.exit(main())
