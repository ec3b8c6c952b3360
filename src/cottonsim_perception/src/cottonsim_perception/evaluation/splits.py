"""Evaluate a Cotton-Eye network on labelled splits: the paper's Table 3 numbers.

Why: to compare our YOLO-style models with the paper (segmentation test
P 93.0 / R 88.9 / mAP50 85.2; boll detection P 94.8 / R 87.2 / mAP50 92.7)
on the same data (the original Segmentation valid + test and Detection valid +
test splits) and with the same definitions (see ``evaluation.metrics``).

Layers (the command line is :mod:`cottonsim_perception.evaluation.cli`):

* :func:`evaluate_predictions` is the pure core: Detections + GroundTruth of
  every image -> a result dict (no files, no network), used by the tests.
* :func:`load_ground_truth` reads one split of a YOLO-format dataset.
* :func:`evaluate_split` runs any object with ``predict(image_rgb) ->
  Detections`` over a split.
* :func:`manifest_groups` splits a split's images by a column of the
  ``manifest.csv`` that ``generate_dataset`` writes.

Result dict layout (also the JSON)::

    {"task": "seg", "class_names": [...], "num_images": 20, "ignored_predictions": 0,
     "mask": {"conf_threshold": 0.41, "rows": [row_all, row_class0, ...]},
     "box":  {...same...}}            # "mask" only for task 'seg'

    row = {"class": "all" | name, "images": int, "instances": int,
           "p": float, "r": float, "map50": float, "map50_95": float,
           "ap50_eq3": float, "tp": int, "fp": int, "fn": int}

P / R / mAP are fractions (0..1); classes without ground truth have null
metrics and are left out of the 'all' row. ``ignored_predictions`` counts
the predictions dropped because they lie on an image's ignore boxes
(``yolo_format.ignore_path_for``; simulator boll labels only).
"""
from __future__ import annotations

import math
import os
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from cottonsim_perception.data import yolo_format as yf
from cottonsim_perception.evaluation import metrics as M
from cottonsim_perception.types import Detections, GroundTruth


def _metric_rows(per: M.PerClassMetrics, class_names: Sequence[str],
                 images_per_class: np.ndarray, num_images: int) -> Dict[str, object]:
    def f(x) -> Optional[float]:
        x = float(x)
        return None if math.isnan(x) else x

    summ = per.summary()
    rows = [{"class": "all", "images": int(num_images), "instances": int(per.n_gt.sum()),
             "p": f(summ["p"]), "r": f(summ["r"]), "map50": f(summ["map50"]),
             "map50_95": f(summ["map50_95"]), "ap50_eq3": f(summ["ap50_eq3"]),
             "tp": int(per.tp[per.valid].sum()), "fp": int(per.fp[per.valid].sum()),
             "fn": int(per.fn[per.valid].sum())}]
    for c, name in enumerate(class_names):
        rows.append({"class": str(name), "images": int(images_per_class[c]),
                     "instances": int(per.n_gt[c]), "p": f(per.p[c]), "r": f(per.r[c]),
                     "map50": f(per.ap[c, 0]), "map50_95": f(np.mean(per.ap[c])),
                     "ap50_eq3": f(per.ap50_eq3[c]), "tp": int(per.tp[c]), "fp": int(per.fp[c]),
                     "fn": int(per.fn[c])})
    return {"conf_threshold": per.conf_threshold, "rows": rows}


def evaluate_predictions(detections: Sequence[Detections], ground_truths: Sequence[GroundTruth],
                         class_names: Sequence[str], task: str,
                         iou_thresholds=M.IOU_THRESHOLDS, matching: str = "score",
                         ap_method: str = "ultralytics") -> Dict[str, object]:
    """Metrics of a whole split from per-image predictions and labels (see module docstring).

    detections[i] and ground_truths[i] belong to the same image. For task
    'seg' both must carry masks of the same size; 'mask' metrics use
    :func:`metrics.mask_iou`, 'box' metrics :func:`metrics.box_iou`.
    Raises ValueError for mismatched lengths, class ids outside class_names,
    or missing / mis-sized masks (naming the image index).
    """
    if task not in yf.TASKS:
        raise ValueError(f"task must be one of {yf.TASKS}, got {task!r}")
    if len(detections) != len(ground_truths):
        raise ValueError(f"{len(detections)} predictions for {len(ground_truths)} images")
    nc = len(class_names)
    if nc == 0:
        raise ValueError("class_names is empty")
    thr = np.asarray(iou_thresholds, dtype=np.float64).reshape(-1)
    kinds = ["mask", "box"] if task == "seg" else ["box"]
    tps = {k: [] for k in kinds}
    confs, pcls, gcls = [], [], []
    images_per_class = np.zeros(nc, dtype=np.int64)
    num_ignored = 0
    for i, (det, gt) in enumerate(zip(detections, ground_truths)):
        for what, cls in (("prediction", det.classes), ("ground truth", gt.classes)):
            if len(cls) and (cls.min() < 0 or cls.max() >= nc):
                raise ValueError(f"image {i}: {what} class id {int(cls.max())} outside 0..{nc - 1}")
        for c in np.unique(gt.classes):
            images_per_class[int(c)] += 1
        for kind in kinds:
            if kind == "mask":
                if det.masks is None or gt.masks is None:
                    raise ValueError(f"image {i}: task 'seg' needs masks in both the "
                                     f"predictions and the ground truth")
                if len(det) and len(gt) and det.masks.shape[1:] != gt.masks.shape[1:]:
                    raise ValueError(f"image {i}: predicted masks {det.masks.shape[1:]} and "
                                     f"ground-truth masks {gt.masks.shape[1:]} differ in size")
                iou = M.mask_iou(det.masks, gt.masks) if len(det) and len(gt) else \
                    np.zeros((len(det), len(gt)))
            else:
                iou = M.box_iou(det.boxes_xyxy, gt.boxes_xyxy)
            tps[kind].append(M.match_predictions(det.classes, gt.classes, iou, thr,
                                                 scores=det.scores, method=matching))
        keep = np.ones(len(det), dtype=bool)
        if gt.ignore_boxes_xyxy is not None and len(gt.ignore_boxes_xyxy) and len(det):
            # unmatched (in every kind) predictions on don't-care regions count nowhere
            matched = np.zeros(len(det), dtype=bool)
            for kind in kinds:
                matched |= tps[kind][-1][:, 0]
            keep = ~M.on_ignore_regions(det.boxes_xyxy, matched, gt.ignore_boxes_xyxy)
            for kind in kinds:
                tps[kind][-1] = tps[kind][-1][keep]
            num_ignored += int(np.count_nonzero(~keep))
        confs.append(np.asarray(det.scores, dtype=np.float64)[keep])
        pcls.append(np.asarray(det.classes, dtype=np.int64)[keep])
        gcls.append(np.asarray(gt.classes, dtype=np.int64))
    conf = np.concatenate(confs) if confs else np.zeros(0)
    pc = np.concatenate(pcls) if pcls else np.zeros(0, np.int64)
    gc = np.concatenate(gcls) if gcls else np.zeros(0, np.int64)
    result: Dict[str, object] = {"task": task, "class_names": [str(n) for n in class_names],
                                 "num_images": len(detections),
                                 "ignored_predictions": num_ignored,
                                 "iou_thresholds": [float(t) for t in thr],
                                 "matching": matching, "ap_method": ap_method}
    for kind in kinds:
        tp = np.concatenate(tps[kind]) if tps[kind] else np.zeros((0, thr.size), bool)
        per = M.ap_per_class(tp, conf, pc, gc, nc, thr, ap_method)
        result[kind] = _metric_rows(per, class_names, images_per_class, len(detections))
    return result


def format_table(result: Dict[str, object], title: str = "") -> str:
    """The result as a fixed-width text table (percentages), like Ultralytics' val."""
    kinds = [k for k in ("mask", "box") if k in result]
    head = f"{'class':>16} {'images':>7} {'instances':>9}"
    for k in kinds:
        tag = "M" if k == "mask" else "B"
        head += f" {'P(' + tag + ')':>7} {'R(' + tag + ')':>7} {'mAP50':>7} {'mAP50-95':>8}"
    lines = [title] if title else []
    lines.append(head)
    rows0 = result[kinds[0]]["rows"]
    for idx, row in enumerate(rows0):
        line = f"{row['class']:>16} {row['images']:>7d} {row['instances']:>9d}"
        for k in kinds:
            r = result[k]["rows"][idx]
            for key, width in (("p", 7), ("r", 7), ("map50", 7), ("map50_95", 8)):
                v = r[key]
                line += " " + (f"{100 * v:>{width}.1f}" if v is not None else f"{'-':>{width}}")
        lines.append(line)
    return "\n".join(lines)


def load_ground_truth(root: str, split: str, task: str, class_names: Sequence[str],
                      use_ignore: bool = True) -> List[Tuple[str, np.ndarray, GroundTruth]]:
    """(image_path, image_rgb, GroundTruth) of every image of a split, in original pixels.

    use_ignore: read the images' ignore boxes (``yolo_format.ignore_path_for``)
    when they have them; False evaluates as if there were none.

    Raises yolo_format.LabelFormatError for a missing split, no images, an
    unreadable image or a malformed label.
    """
    import cv2

    out = []
    for pair in yf.list_pairs(root, split):
        bgr = cv2.imread(pair.image_path, cv2.IMREAD_COLOR)
        if bgr is None:
            raise yf.LabelFormatError(f"{pair.image_path}: cannot read image")
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        h, w = rgb.shape[:2]
        insts = yf.read_label_file(pair.label_path, task, len(class_names))
        boxes, classes, masks = yf.instances_to_pixels(insts, w, h, with_masks=(task == "seg"))
        ignore = yf.read_ignore_boxes(pair.image_path, w, h) if use_ignore else None
        out.append((pair.image_path, rgb, GroundTruth(boxes, classes, masks, ignore)))
    return out


def drop_below(det: Detections, conf_threshold: float) -> Detections:
    """``det`` without the predictions scored below ``conf_threshold`` (0 keeps all)."""
    if conf_threshold <= 0 or not len(det):
        return det
    keep = det.scores >= conf_threshold
    return Detections(det.boxes_xyxy[keep], det.scores[keep], det.classes[keep],
                      None if det.masks is None else det.masks[keep])


def evaluate_split(predictor, root: str, split: str, task: str, class_names: Sequence[str],
                   conf_threshold: float = 0.0, use_ignore: bool = True, **kwargs):
    """Run ``predictor.predict`` over a split and evaluate (kwargs go to evaluate_predictions).

    Returns (result dict, list of Detections, list of GroundTruth).

    Predictions below ``conf_threshold`` are dropped (the predictor may
    already do it).
    """
    items = load_ground_truth(root, split, task, class_names, use_ignore)
    dets, gts = [], []
    for _path, rgb, gt in items:
        dets.append(drop_below(predictor.predict(rgb), conf_threshold))
        gts.append(gt)
    return evaluate_predictions(dets, gts, class_names, task, **kwargs), dets, gts


MANIFEST_FILE = "manifest.csv"


def manifest_groups(root: str, image_paths: Sequence[str], column: str) -> Dict[str, List[int]]:
    """Indices into ``image_paths`` per value of ``column`` of ``root``'s manifest.csv (sorted by value).

    The manifest is the one ``generate_dataset`` writes: one row per image,
    its ``file`` column relative to ``root``. Raises ValueError when the
    manifest is missing, has no such column or lacks one of the images.
    """
    import csv

    path = os.path.join(root, MANIFEST_FILE)
    if not os.path.isfile(path):
        raise ValueError(f"{root!r} has no {MANIFEST_FILE} (generate_dataset writes one); grouping needs it")
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        columns = list(reader.fieldnames or [])
        if column not in columns or column == "file":
            raise ValueError(f"{path} has no column {column!r} to group by; it has {', '.join(columns)}")
        if "file" not in columns:
            raise ValueError(f"{path} has no 'file' column")
        value_of = {os.path.normpath(row["file"]): row[column] for row in reader}
    groups: Dict[str, List[int]] = {}
    for i, image in enumerate(image_paths):
        rel = os.path.normpath(os.path.relpath(image, root))
        if rel not in value_of:
            raise ValueError(f"{image} is not listed in {path}")
        groups.setdefault(value_of[rel], []).append(i)
    return dict(sorted(groups.items()))
