"""The ``evaluate`` command (``rosrun cottonsim_perception evaluate``): a network on labelled splits.

::

    evaluate --task seg|det --data DIR --weights W --json OUT
             [--split valid,test] [--conf 0.001] [--iou 0.7] [--mask-threshold T] [--no-ignore]
             [--flip-tta] [--backend torch|onnxruntime] [--group-by COLUMN]

DIR is a YOLO-format dataset: a data.yaml naming the splits (as Ultralytics
reads it), a Roboflow export or Ultralytics' split folders (see
``yolo_format.layout``). It prints one table per split (class, images,
instances, P, R, mAP50, mAP50-95; for 'seg' both mask and box metrics) and
writes the same to JSON (layout: :mod:`cottonsim_perception.evaluation.splits`).
With several splits it also evaluates their union ('+'-joined name).
``--group-by`` (a column of the ``manifest.csv`` that ``generate_dataset``
writes: mode, camera, growth_stage, farm_seed, ...) adds one table per value
of that column within each split, in the JSON under
``"groups": {"column": COLUMN, "splits": {split: {value: result}}}``.
Exit code 0 on success, 2 with a one-line message for a missing folder, a
split without images, malformed labels, missing / unloadable weights or a
task mismatch.
"""
from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import os
import sys
from typing import Callable, Dict, Optional, Sequence

from cottonsim_perception.data import yolo_format as yf
from cottonsim_perception.evaluation.splits import evaluate_predictions, evaluate_split, format_table, manifest_groups

EXIT_USAGE = 2


def _default_predictor_factory(weights: str, conf: float, iou: float, backend: str = "torch"):
    from cottonsim_perception.inference import Predictor

    return Predictor(weights, conf_threshold=conf, iou_threshold=iou, backend=backend)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="evaluate", description="Evaluate a Cotton-Eye network "
                                "on YOLO-format splits (P, R, mAP50, mAP50-95).")
    p.add_argument("--task", required=True, choices=list(yf.TASKS), help="seg or det")
    p.add_argument("--data", required=True, help="dataset folder: a data.yaml naming the splits, a Roboflow "
                   "export or Ultralytics' images/<split> folders")
    p.add_argument("--weights", required=True, help="checkpoint of the network")
    p.add_argument("--json", required=True, help="output JSON file")
    p.add_argument("--split", default="valid,test", help="comma-separated splits (default valid,test)")
    p.add_argument("--conf", type=float, default=0.001, help="confidence threshold (default 0.001)")
    p.add_argument("--iou", type=float, default=0.7, help="NMS IoU threshold (default 0.7)")
    p.add_argument("--mask-threshold", type=float, default=None,
                   help="mask pixel probability threshold, seg only (default: the value calibrated for the "
                        "weights and stored in them, else 0.5)")
    p.add_argument("--no-ignore", action="store_true",
                   help="count predictions on the images' ignore boxes as false positives "
                        "(default: drop them, see the module docstring)")
    p.add_argument("--flip-tta", action="store_true",
                   help="det only: also run the network on each image mirrored left-right and merge the "
                        "boxes in one NMS (test-time augmentation, Predictor's flip_tta)")
    p.add_argument("--backend", choices=("torch", "onnxruntime"), default="torch",
                   help="inference backend (default torch; onnxruntime runs the .onnx export beside the weights, "
                        "as the nodes do)")
    p.add_argument("--group-by", metavar="COLUMN", default=None,
                   help="also evaluate each value of this column of DIR/manifest.csv (generate_dataset's: "
                        "mode, camera, growth_stage, farm_seed, ...) separately")
    return p


def _fail(message: str) -> int:
    print(f"evaluate: error: {message}", file=sys.stderr)
    return EXIT_USAGE


def main(argv: Optional[Sequence[str]] = None,
         predictor_factory: Optional[Callable[[str, float, float], object]] = None) -> int:
    """The CLI; returns the exit code. ``predictor_factory(weights, conf, iou)`` is
    injectable for tests (default: :class:`cottonsim_perception.inference.Predictor`)."""
    args = build_parser().parse_args(argv)
    if not (0.0 <= args.conf <= 1.0):
        return _fail(f"--conf must be in [0, 1], got {args.conf}")
    if not (0.0 < args.iou <= 1.0):
        return _fail(f"--iou must be in (0, 1], got {args.iou}")
    if args.mask_threshold is not None and not (0.0 < args.mask_threshold < 1.0):
        return _fail(f"--mask-threshold must be in (0, 1), got {args.mask_threshold}")
    if args.flip_tta and args.task != "det":
        return _fail("--flip-tta applies to detection weights only")
    splits = [s.strip() for s in args.split.split(",") if s.strip()]
    if not splits:
        return _fail("--split names no split")
    if not os.path.isdir(args.data):
        return _fail(f"dataset folder {args.data!r} does not exist")
    if not os.path.isfile(args.weights):
        return _fail(f"weights file {args.weights!r} does not exist")
    factory = predictor_factory or functools.partial(_default_predictor_factory, backend=args.backend)
    try:
        predictor = factory(args.weights, args.conf, args.iou)
    except Exception as exc:  # any load failure becomes one clear line
        return _fail(f"cannot load weights {args.weights!r}: {type(exc).__name__}: {exc}")
    ptask = getattr(predictor, "task", args.task)
    if ptask != args.task:
        return _fail(f"weights are a {ptask!r} model but --task is {args.task!r}")
    post_config = getattr(predictor, "post_config", None)
    if args.mask_threshold is not None:
        if args.task != "seg" or post_config is None:
            return _fail("--mask-threshold applies to segmentation weights only")
        predictor.post_config = post_config = dataclasses.replace(post_config, mask_threshold=args.mask_threshold)
    if args.flip_tta:
        predictor.flip_tta = True
    try:
        names = tuple(getattr(predictor, "class_names", None) or yf.class_names_for(args.data, args.task))
        # Check every split (and its groups) before the (slow) prediction runs.
        pairs = {s: yf.list_pairs(args.data, s) for s in splits}
        groups = {s: manifest_groups(args.data, [pr.image_path for pr in pairs[s]], args.group_by)
                  for s in splits} if args.group_by else {}
        out: Dict[str, object] = {"weights": os.path.abspath(args.weights),
                                  "data": os.path.abspath(args.data),
                                  "conf": args.conf, "iou": args.iou,
                                  "mask_threshold": getattr(post_config, "mask_threshold", None)
                                  if args.task == "seg" else None,
                                  "ignore_boxes": not args.no_ignore, "flip_tta": args.flip_tta,
                                  "backend": args.backend,
                                  "splits": {}}
        if groups:
            out["groups"] = {"column": args.group_by, "splits": {}}
        all_dets, all_gts = [], []
        for s in splits:
            res, dets, gts = evaluate_split(predictor, args.data, s, args.task, names,
                                            conf_threshold=args.conf, use_ignore=not args.no_ignore)
            out["splits"][s] = res
            all_dets += dets
            all_gts += gts
            print(format_table(res, title=f"== {s} ({res['num_images']} images)"))
            for value, idx in groups.get(s, {}).items():
                res_g = evaluate_predictions([dets[i] for i in idx], [gts[i] for i in idx], names, args.task)
                out["groups"]["splits"].setdefault(s, {})[value] = res_g
                print(format_table(res_g, title=f"== {s} [{args.group_by} = {value}] ({len(idx)} images)"))
        if len(splits) > 1:
            name = "+".join(splits)
            res = evaluate_predictions(all_dets, all_gts, names, args.task)
            out["splits"][name] = res
            print(format_table(res, title=f"== {name} ({res['num_images']} images)"))
    except (yf.LabelFormatError, ValueError) as exc:
        return _fail(str(exc))
    try:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(out, fh, indent=2)
    except OSError as exc:
        return _fail(f"cannot write {args.json!r}: {exc}")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
