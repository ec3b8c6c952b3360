"""YOLO label files: one line per instance, parsed, validated and written.

Label files (one ``.txt`` per image, one instance per line, all coordinates
normalised to [0, 1] by the image width / height):

* segmentation: ``cls x1 y1 x2 y2 ... xn yn`` (a polygon of n >= 3 points);
* detection:    ``cls cx cy w h`` (box centre and size).

A detection dataset may also contain polygon lines (Roboflow exports mix them);
they are read as the polygon's bounding box. A segmentation dataset must have
polygons. Blank lines are ignored; an image without a label file is a
background image (no instances).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import List, Optional, Sequence

import numpy as np

#: Class names of the original CottonSim datasets (paper Section 2.5).
SEGMENTATION_CLASS_NAMES = ("cotton plants", "ground", "sky")
DETECTION_CLASS_NAMES = ("cotton boll",)

#: How far outside [0, 1] a normalised coordinate may lie (rounding in
#: exporters) before the line is rejected; values within it are clipped.
DEFAULT_RANGE_TOLERANCE = 0.01

TASKS = ("seg", "det")


class LabelFormatError(ValueError):
    """A malformed label file, data.yaml or folder; the message names the file (and line)."""


@dataclass(frozen=True)
class LabelInstance:
    """One labelled instance, in normalised image coordinates.

    class_id: int >= 0; box_cxcywh: (4,) float64 centre x, centre y, width,
    height in [0, 1]; polygon: (K, 2) float64 x, y points in [0, 1] (K >= 3)
    or None for box-only labels.
    """

    class_id: int
    box_cxcywh: np.ndarray
    polygon: Optional[np.ndarray] = None

    def box_xyxy_px(self, width: int, height: int) -> np.ndarray:
        """The box as (x1, y1, x2, y2) [px] of a width x height image."""
        cx, cy, w, h = self.box_cxcywh
        return np.array([(cx - w / 2) * width, (cy - h / 2) * height,
                         (cx + w / 2) * width, (cy + h / 2) * height], dtype=np.float64)

    def polygon_px(self, width: int, height: int) -> Optional[np.ndarray]:
        """The polygon as (K, 2) [px] of a width x height image, or None."""
        if self.polygon is None:
            return None
        return self.polygon * np.array([width, height], dtype=np.float64)


def check_task(task: str) -> None:
    """Raise ValueError unless ``task`` is one of ``TASKS``."""
    if task not in TASKS:
        raise ValueError(f"task must be one of {TASKS}, got {task!r}")


def polygon_bbox_cxcywh(polygon: np.ndarray) -> np.ndarray:
    """Bounding box (cx, cy, w, h) of a (K, 2) polygon, in the polygon's units."""
    p = np.asarray(polygon, dtype=np.float64).reshape(-1, 2)
    if p.shape[0] == 0:
        raise ValueError("polygon_bbox_cxcywh: empty polygon")
    x1, y1 = p.min(axis=0)
    x2, y2 = p.max(axis=0)
    return np.array([(x1 + x2) / 2, (y1 + y2) / 2, x2 - x1, y2 - y1], dtype=np.float64)


def polygon_bbox_xyxy(polygon: np.ndarray) -> np.ndarray:
    """Bounding box (x1, y1, x2, y2) of a (K, 2) polygon, in the polygon's units."""
    p = np.asarray(polygon, dtype=np.float64).reshape(-1, 2)
    if p.shape[0] == 0:
        raise ValueError("polygon_bbox_xyxy: empty polygon")
    return np.concatenate([p.min(axis=0), p.max(axis=0)])


def parse_label_line(line: str, task: str, num_classes: Optional[int] = None,
                     source: str = "<string>", line_number: int = 1,
                     tolerance: float = DEFAULT_RANGE_TOLERANCE) -> Optional[LabelInstance]:
    """Parse one label line; returns None for a blank line.

    Raises :class:`LabelFormatError` naming ``source:line_number`` for a bad
    class id (not an integer, negative, or >= num_classes when given), a wrong
    number of values, an odd number of polygon coordinates, NaN / inf, or
    values outside [-tolerance, 1 + tolerance]. Values within the tolerance
    are clipped to [0, 1].
    """
    check_task(task)
    where = f"{source}:{line_number}"
    parts = line.split()
    if not parts:
        return None
    try:
        cls_f = float(parts[0])
    except ValueError:
        raise LabelFormatError(f"{where}: class id {parts[0]!r} is not a number") from None
    if not math.isfinite(cls_f) or cls_f != int(cls_f) or cls_f < 0:
        raise LabelFormatError(f"{where}: class id {parts[0]!r} is not a non-negative integer")
    cls = int(cls_f)
    if num_classes is not None and cls >= num_classes:
        raise LabelFormatError(f"{where}: class id {cls} out of range (dataset has {num_classes} classes)")
    try:
        values = np.array([float(v) for v in parts[1:]], dtype=np.float64)
    except ValueError as exc:
        raise LabelFormatError(f"{where}: non-numeric coordinate ({exc})") from None
    if not np.all(np.isfinite(values)):
        raise LabelFormatError(f"{where}: NaN or inf coordinate")
    n = values.size
    if n == 4:
        if task == "seg":
            raise LabelFormatError(f"{where}: segmentation label needs a polygon "
                                   f"'cls x1 y1 ... xn yn' with >= 3 points, got a box (4 values)")
    elif n % 2 == 1:
        raise LabelFormatError(f"{where}: odd number of polygon coordinates ({n})")
    elif n < 6:
        raise LabelFormatError(f"{where}: expected 4 box values or >= 6 polygon coordinates, got {n}")
    if np.any(values < -tolerance) or np.any(values > 1.0 + tolerance):
        bad = values[(values < -tolerance) | (values > 1.0 + tolerance)][0]
        raise LabelFormatError(f"{where}: coordinate {bad:g} outside [0, 1] "
                               f"(normalised coordinates expected)")
    values = values.clip(0.0, 1.0)
    if n == 4:
        cx, cy, w, h = values
        if w <= 0.0 or h <= 0.0:
            raise LabelFormatError(f"{where}: box width and height must be > 0, got {w:g} x {h:g}")
        # A box may stick out a little after clipping its centre; keep it inside.
        x1, y1 = max(cx - w / 2, 0.0), max(cy - h / 2, 0.0)
        x2, y2 = min(cx + w / 2, 1.0), min(cy + h / 2, 1.0)
        box = np.array([(x1 + x2) / 2, (y1 + y2) / 2, x2 - x1, y2 - y1])
        return LabelInstance(cls, box, None)
    polygon = values.reshape(-1, 2)
    return LabelInstance(cls, polygon_bbox_cxcywh(polygon), polygon)


def read_label_file(path: str, task: str, num_classes: Optional[int] = None,
                    tolerance: float = DEFAULT_RANGE_TOLERANCE) -> List[LabelInstance]:
    """All instances of one label file; a missing file means no instances.

    For task 'det' polygons are kept (their box is what detection uses).
    """
    check_task(task)
    if not os.path.exists(path):
        return []
    try:
        with open(path, "r", encoding="utf-8") as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise LabelFormatError(f"{path}: cannot read label file ({exc})") from None
    out = []
    for i, line in enumerate(text.splitlines(), start=1):
        inst = parse_label_line(line, task, num_classes, path, i, tolerance)
        if inst is not None:
            out.append(inst)
    return out


def format_label_line(instance: LabelInstance, task: str, precision: int = 6) -> str:
    """One label line for ``instance``: a polygon for 'seg', a box for 'det'."""
    check_task(task)
    if task == "seg":
        if instance.polygon is None:
            raise ValueError("format_label_line: a segmentation label needs a polygon")
        vals = np.asarray(instance.polygon, dtype=np.float64).reshape(-1)
    else:
        vals = np.asarray(instance.box_cxcywh, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(vals)):
        raise ValueError("format_label_line: NaN or inf coordinate")
    vals = vals.clip(0.0, 1.0)
    return " ".join([str(int(instance.class_id))] + [f"{v:.{precision}f}" for v in vals])


def write_label_file(path: str, instances: Sequence[LabelInstance], task: str) -> None:
    """Write instances as a label file (creates the folder)."""
    lines = [format_label_line(inst, task) for inst in instances]
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("\n".join(lines) + ("\n" if lines else ""))
