"""Ultralytics-YOLO dataset format: label files, data.yaml, folder layouts, masks.

Why: the paper's data (Roboflow export of the original CottonSim datasets) and
the datasets our generator writes are in this format, and both training and
evaluation read it; one careful reader means one set of error messages.

Label files (one ``.txt`` per image, one instance per line, all coordinates
normalised to [0, 1] by the image width / height):

* segmentation: ``cls x1 y1 x2 y2 ... xn yn`` (a polygon of n >= 3 points);
* detection:    ``cls cx cy w h`` (box centre and size).

A detection dataset may also contain polygon lines (Roboflow exports mix them);
they are read as the polygon's bounding box. A segmentation dataset must have
polygons. Blank lines are ignored; an image without a label file is a
background image (no instances).

Folder layouts understood by :func:`find_split`:

* Roboflow export (the paper's data; no data.yaml): ``DIR/{train,valid,test}/images``
  and ``DIR/{train,valid,test}/labels``;
* Ultralytics: ``DIR/images/{train,val,test}`` and ``DIR/labels/{train,val,test}``;
* a ``DIR/data.yaml`` (keys path, train, val, test, names) naming the image
  folders of each split, labels found by replacing the last ``images`` folder
  of an image's path with ``labels``.

The split names 'valid' and 'val' are synonyms.

Pixel convention: pixel-edge coordinates, x right, y down; a polygon point
(1, 1) normalised is the bottom-right corner (W, H) [px] of the image.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple

import cv2
import numpy as np

IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp")

#: Class names of the original CottonSim datasets (paper Section 2.5).
SEGMENTATION_CLASS_NAMES = ("cotton plants", "ground", "sky")
DETECTION_CLASS_NAMES = ("cotton boll",)

#: How far outside [0, 1] a normalised coordinate may lie (rounding in
#: exporters) before the line is rejected; values within it are clipped.
DEFAULT_RANGE_TOLERANCE = 0.01

TASKS = ("seg", "det")

_SPLIT_ALIASES = {"valid": ("valid", "val"), "val": ("val", "valid"),
                  "train": ("train",), "test": ("test",)}


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


def _check_task(task: str) -> None:
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
    _check_task(task)
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
    _check_task(task)
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
    _check_task(task)
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


# --------------------------------------------------------------------------- data.yaml

@dataclass(frozen=True)
class DataYaml:
    """Contents of an Ultralytics data.yaml.

    path: dataset root (absolute or relative to the yaml's folder); train, val,
    test: image folders relative to path ('' when absent); names: class names
    in id order.
    """

    path: str
    train: str
    val: str
    test: str = ""
    names: Tuple[str, ...] = field(default_factory=tuple)


def read_data_yaml(path: str) -> DataYaml:
    """Read a data.yaml; names may be a list or an {id: name} mapping."""
    from cottonsim_common.config.yaml_files import load_yaml_file

    try:
        raw = load_yaml_file(path)
    except ValueError as exc:
        raise LabelFormatError(f"data.yaml: {exc}") from None
    if not isinstance(raw, dict):
        raise LabelFormatError(f"{path}: expected a mapping at top level")
    names = raw.get("names", [])
    if isinstance(names, dict):
        try:
            ids = sorted(int(k) for k in names)
        except (TypeError, ValueError):
            raise LabelFormatError(f"{path}: 'names' keys must be integer class ids") from None
        if ids != list(range(len(ids))):
            raise LabelFormatError(f"{path}: 'names' ids must be 0..{len(ids) - 1}")
        names = [names[k] if k in names else names[str(k)] for k in ids]
    if not isinstance(names, (list, tuple)):
        raise LabelFormatError(f"{path}: 'names' must be a list or a mapping")
    root = raw.get("path") or ""
    if not os.path.isabs(root):
        root = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)), root))
    return DataYaml(path=root, train=str(raw.get("train") or ""), val=str(raw.get("val") or ""),
                    test=str(raw.get("test") or ""), names=tuple(str(n) for n in names))


def write_data_yaml(path: str, data: DataYaml) -> None:
    """Write a data.yaml (names as a list).

    An empty ``data.path`` writes no 'path' key: readers (this module, Ultralytics) then take
    the yaml's own folder as the root, so the dataset folder can be moved or copied.
    """
    import yaml

    content = {"path": data.path} if data.path else {}
    content.update({"train": data.train, "val": data.val, "test": data.test,
                    "nc": len(data.names), "names": list(data.names)})
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", encoding="utf-8") as fh:
        yaml.safe_dump(content, fh, sort_keys=False)


def class_names_for(root: str, task: str) -> Tuple[str, ...]:
    """The dataset's class names: from DIR/data.yaml if present, else the paper's."""
    _check_task(task)
    yaml_path = os.path.join(root, "data.yaml")
    if os.path.isfile(yaml_path):
        names = read_data_yaml(yaml_path).names
        if names:
            return names
    return SEGMENTATION_CLASS_NAMES if task == "seg" else DETECTION_CLASS_NAMES


# --------------------------------------------------------------------------- layouts

#: Folder of the ignore-box files, beside ``labels`` (see :func:`ignore_path_for`).
IGNORE_FOLDER = "ignore"

@dataclass(frozen=True)
class ImageLabelPair:
    """One image file and the label file that belongs to it (which may not exist)."""

    image_path: str
    label_path: str


def _sibling_txt_path(image_path: str, folder: str) -> str:
    """The image's path with its last 'images' folder renamed ``folder`` and extension '.txt'."""
    head, name = os.path.split(image_path)
    parts = head.split(os.sep)
    for i in range(len(parts) - 1, -1, -1):
        if parts[i] == "images":
            parts[i] = folder
            break
    stem = os.path.splitext(name)[0]
    return os.path.join(os.sep.join(parts), stem + ".txt")


def label_path_for(image_path: str) -> str:
    """Ultralytics' rule: the last '/images/' folder becomes '/labels/', extension '.txt'."""
    return _sibling_txt_path(image_path, "labels")


def ignore_path_for(image_path: str) -> str:
    """The image's ignore-box file: the last '/images/' folder becomes '/ignore/'.

    Ignore boxes (our extension of the format, written by the dataset
    generator for bolls outside its labelling rules; Ultralytics does not
    read them) are YOLO box lines of objects that are neither required nor
    forbidden: an unmatched prediction lying on one is not a false positive
    (``evaluate``), and the training loss does not push the anchors inside
    one towards background (``nn.loss``).
    """
    return _sibling_txt_path(image_path, IGNORE_FOLDER)


def read_ignore_instances(image_path: str) -> List[LabelInstance]:
    """The image's ignore boxes as box lines (normalised; empty when it has no ignore file).

    Raises :class:`LabelFormatError` for a malformed ignore file.
    """
    path = ignore_path_for(image_path)
    return read_label_file(path, "det", 1) if os.path.isfile(path) else []


def read_ignore_boxes(image_path: str, width: int, height: int) -> np.ndarray:
    """(K, 4) float32 ignore boxes xyxy [px] of an image (empty when it has no ignore file)."""
    return np.array([inst.box_xyxy_px(width, height) for inst in read_ignore_instances(image_path)],
                    dtype=np.float32).reshape(-1, 4)


def _list_images(folder: str) -> List[str]:
    files = []
    for dirpath, _dirs, names in os.walk(folder):
        for n in names:
            if n.lower().endswith(IMAGE_EXTENSIONS):
                files.append(os.path.join(dirpath, n))
    return sorted(files)


def find_split(root: str, split: str) -> str:
    """The image folder of ``split`` under ``root`` (any of the three layouts).

    Raises :class:`LabelFormatError` naming the folders tried when none exists.
    """
    if not os.path.isdir(root):
        raise LabelFormatError(f"dataset folder {root!r} does not exist")
    aliases = _SPLIT_ALIASES.get(split, (split,))
    tried = []
    yaml_path = os.path.join(root, "data.yaml")
    if os.path.isfile(yaml_path):
        dy = read_data_yaml(yaml_path)
        entries = {"train": dy.train, "val": dy.val, "valid": dy.val, "test": dy.test}
        rel = entries.get(split, "")
        if rel:
            cand = rel if os.path.isabs(rel) else os.path.normpath(os.path.join(dy.path, rel))
            tried.append(cand)
            if os.path.isdir(cand):
                return cand
    for name in aliases:
        for cand in (os.path.join(root, name, "images"), os.path.join(root, "images", name)):
            tried.append(cand)
            if os.path.isdir(cand):
                return cand
    raise LabelFormatError(f"split {split!r} not found under {root!r}; tried: {', '.join(tried)}")


def list_pairs(root: str, split: str) -> List[ImageLabelPair]:
    """Sorted image / label pairs of a split; raises when the split has no images."""
    folder = find_split(root, split)
    images = _list_images(folder)
    if not images:
        raise LabelFormatError(f"no images ({', '.join(IMAGE_EXTENSIONS)}) in {folder!r}")
    return [ImageLabelPair(p, label_path_for(p)) for p in images]


# --------------------------------------------------------------------------- masks

def polygon_to_mask(polygon_px: np.ndarray, height: int, width: int) -> np.ndarray:
    """Rasterise a (K, 2) polygon in pixel-edge coordinates into an (H, W) bool mask.

    A pixel belongs to the mask when its centre lies inside the polygon
    (even-odd rule; a centre exactly on a left / top edge counts as inside, on
    a right / bottom edge as outside), so a rectangle [10, 30] x [10, 20]
    covers exactly 20 x 10 pixels and [0, W] x [0, H] the whole image.
    cv2.fillPoly is not used here: it fills every pixel the outline touches,
    which adds about half a pixel all round (a 10 px boll would gain ~20 %).
    Implementation: a vectorised scanline - the polygon's edges are crossed
    with every row's centre line, the crossings toggle a per-row parity
    counter at the first pixel centre right of them.
    """
    h, w = int(height), int(width)
    p = np.asarray(polygon_px, dtype=np.float64).reshape(-1, 2)
    if p.shape[0] < 3 or not np.all(np.isfinite(p)) or h <= 0 or w <= 0:
        return np.zeros((max(h, 0), max(w, 0)), dtype=bool)
    q = np.roll(p, -1, axis=0)
    r0 = max(int(np.floor(p[:, 1].min() - 0.5)), 0)
    r1 = min(int(np.ceil(p[:, 1].max() + 0.5)), h)
    mask = np.zeros((h, w), dtype=bool)
    if r1 <= r0:
        return mask
    yc = np.arange(r0, r1) + 0.5                          # row centre lines
    y0, y1 = p[:, 1:2], q[:, 1:2]
    crosses = (np.minimum(y0, y1) <= yc) & (yc < np.maximum(y0, y1))
    k, r = np.nonzero(crosses)                           # edge index, row index
    t = (yc[r] - p[k, 1]) / (q[k, 1] - p[k, 1])
    x = p[k, 0] + t * (q[k, 0] - p[k, 0])
    col = np.clip(np.ceil(x - 0.5), 0, w).astype(np.int64)  # first centre at or right of x
    toggles = np.zeros((r1 - r0, w + 1), dtype=np.int32)
    np.add.at(toggles, (r, col), 1)
    mask[r0:r1] = (np.cumsum(toggles, axis=1)[:, :w] & 1).astype(bool)
    return mask


def mask_to_polygons(mask: np.ndarray, epsilon_px: float = 1.0,
                     min_area_px: float = 4.0) -> List[np.ndarray]:
    """Outer contours of a bool mask as simplified (K, 2) polygons [px, pixel edges].

    Each connected region gives one polygon (holes are ignored: YOLO labels
    have no holes). The contour is traced (cv2.findContours) on the mask
    upsampled 2x, which puts it a quarter pixel inside the region's outer
    pixel edges: every boundary pixel's centre is inside, every outside
    pixel's centre outside, so polygon_to_mask(p) reproduces the (hole-free)
    mask exactly without simplification. ``epsilon_px`` is the
    Douglas-Peucker tolerance [px] (0: none); regions whose polygon area is
    below ``min_area_px`` [px^2] are dropped.
    """
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask_to_polygons: expected an (H, W) mask, got shape {m.shape}")
    if not np.any(m):
        return []
    up = cv2.resize((m > 0).astype(np.uint8), None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
    contours, _ = cv2.findContours(up, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    polys = []
    for c in contours:
        if c.shape[0] < 3 or cv2.contourArea(c) / 4.0 < min_area_px:
            continue
        approx = cv2.approxPolyDP(c, 2.0 * float(epsilon_px), True) if epsilon_px > 0 else c
        pts = (approx.reshape(-1, 2).astype(np.float64) + 0.5) / 2.0
        if pts.shape[0] >= 3:
            polys.append(pts)
    return polys


def join_polygons(polygons: Sequence[np.ndarray]) -> np.ndarray:
    """Join several (K_i, 2) polygons into one vertex list by zero-width bridges.

    Why: a YOLO segmentation line holds one polygon, while the paper's labels
    (and the scene segmenter's predictions) have one instance per class, which
    may be many separate regions. The polygons are visited in a greedy
    nearest-neighbour order of their first vertices; after each polygon the path closes it (repeats
    its first vertex) and steps to the next one; after the last polygon it
    walks the same bridges back, so every bridge is traversed twice and adds
    no area under the even-odd rule of :func:`polygon_to_mask`: the result
    rasterises to the XOR of the inputs' masks, i.e. their union when they do
    not overlap (outlines and holes of a label set never do). A single polygon
    is returned unchanged. Raises ValueError for an empty list or a polygon
    with fewer than 3 points.
    """
    polys = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in polygons]
    if not polys:
        raise ValueError("join_polygons: no polygons")
    for i, p in enumerate(polys):
        if p.shape[0] < 3:
            raise ValueError(f"join_polygons: polygon {i} has {p.shape[0]} points (>= 3 needed)")
    if len(polys) == 1:
        return polys[0].copy()
    firsts = np.array([p[0] for p in polys])       # ordering by first vertices: O(n^2) scalars
    left = np.ones(len(polys), dtype=bool)
    left[0] = False
    order = [0]
    for _ in range(len(polys) - 1):
        d = np.sum((firsts - firsts[order[-1]]) ** 2, axis=1)
        d[~left] = np.inf
        j = int(np.argmin(d))
        left[j] = False
        order.append(j)
    chain, anchors = [], []
    for j in order:
        p = polys[j]
        if anchors:   # start the polygon at its vertex nearest to the previous anchor
            k = int(np.argmin(np.sum((p - anchors[-1]) ** 2, axis=1)))
            p = np.roll(p, -k, axis=0)
        chain.append(p)
        chain.append(p[:1])                       # close this polygon
        anchors.append(p[0])
    back = [a[None, :] for a in reversed(anchors[1:-1])]   # walk the bridges back
    return np.concatenate(chain + back, axis=0)


def merge_instances_per_class(instances: Sequence[LabelInstance]) -> List[LabelInstance]:
    """One polygon instance per class (the paper's label style), joined by :func:`join_polygons`.

    Box-only instances are kept as they are; the classes come out in
    ascending order, each followed by nothing else of its class.
    """
    by_class: Dict[int, List[np.ndarray]] = {}
    boxes: List[LabelInstance] = []
    for inst in instances:
        if inst.polygon is None:
            boxes.append(inst)
        else:
            by_class.setdefault(int(inst.class_id), []).append(inst.polygon)
    out = []
    for cls in sorted(by_class):
        poly = join_polygons(by_class[cls]).clip(0.0, 1.0)
        out.append(LabelInstance(cls, polygon_bbox_cxcywh(poly), poly))
    return out + boxes


def merge_seg_label_files(root: str) -> Tuple[int, int, int]:
    """Rewrite every ``*.txt`` under ``root`` (recursively, folders named 'labels' only)
    with :func:`merge_instances_per_class`, in place.

    Returns (files, label lines before, lines after). Raises LabelFormatError
    for a malformed line (nothing is half-written: each file is parsed before
    it is rewritten) or when ``root`` holds no label files.
    """
    paths = []
    for dirpath, _dirs, files in os.walk(root):
        if "labels" in dirpath.split(os.sep):
            paths += [os.path.join(dirpath, f) for f in files if f.endswith(".txt")]
    if not paths:
        raise LabelFormatError(f"no label files in a 'labels' folder under {root!r}")
    before = after = 0
    for path in sorted(paths):
        insts = read_label_file(path, "seg")
        merged = merge_instances_per_class(insts)
        before += len(insts)
        after += len(merged)
        write_label_file(path, merged, "seg")
    return len(paths), before, after


def instances_to_pixels(instances: Sequence[LabelInstance], width: int, height: int,
                        with_masks: bool) -> Tuple[np.ndarray, np.ndarray, Optional[np.ndarray]]:
    """Labels of one image as (boxes_xyxy (M, 4) float32 [px], classes (M,) int64, masks).

    masks: (M, H, W) bool rasterised from the polygons when ``with_masks``
    (an instance without a polygon gets its filled box), else None.
    """
    m = len(instances)
    boxes = np.zeros((m, 4), dtype=np.float32)
    classes = np.zeros((m,), dtype=np.int64)
    masks = np.zeros((m, height, width), dtype=bool) if with_masks else None
    for i, inst in enumerate(instances):
        boxes[i] = inst.box_xyxy_px(width, height)
        classes[i] = inst.class_id
        if masks is not None:
            poly = inst.polygon_px(width, height)
            if poly is None:
                x1, y1, x2, y2 = boxes[i]
                poly = np.array([[x1, y1], [x2, y1], [x2, y2], [x1, y2]])
            masks[i] = polygon_to_mask(poly, height, width)
    return boxes, classes, masks
