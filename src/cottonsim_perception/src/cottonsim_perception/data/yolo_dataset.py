"""A torch Dataset over a YOLO-format folder, letterboxed, with augmentations.

Why: the Cotton-Eye networks train on fixed-size inputs (e.g. 640 x 480 or a
smaller 320 x 256) from images of two sizes (640 x 480, 720 x 540). Every item
is letterboxed (uniform scale + grey padding, :mod:`cottonsim_perception.nn.letterbox`)
and, for training, augmented with the YOLOv8-style photometric and geometric
jitter the paper's model was trained with. Geometric augmentations are applied
to the image, the instance polygons (hence masks) and the boxes with the same
matrix so labels stay on their objects.

Item: ``(image, targets)`` with image a (3, H, W) float32 tensor in [0, 1]
(RGB, H x W = imgsz) and targets a dict:

* ``classes``: (M,) int64;
* ``boxes_xyxy``: (M, 4) float32 [px] in the letterboxed image;
* ``masks``: (M, H, W) uint8 (0/1) at the letterboxed size (task 'seg' only);
* ``ignore_boxes_xyxy``: (K, 4) float32 [px] don't-care boxes (task 'det':
  the image's ignore file, ``yolo_format.ignore_path_for``; empty without
  one), moved by the same augmentation as the boxes;
* ``image_path`` (str), ``orig_hw`` ((H0, W0) of the file), ``letterbox``
  (the :class:`LetterboxTransform` that maps original to input pixels).

For 'seg' the boxes are the tight boxes of the (augmented) masks
(x2 = last column + 1); for 'det' they are the labelled boxes, through the
affine as the enclosing box of their four transformed corners, clipped.
Instances that end up (almost) outside the image are dropped.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import cv2
import numpy as np
import torch
from torch.utils.data import Dataset

from cottonsim_perception.data import yolo_format as yf
from cottonsim_perception.nn.letterbox import PAD_VALUE, letterbox


#: Class id that marks an ignore box inside the dataset's arrays (never in a target's classes).
IGNORE_CLASS = -1


@dataclass(frozen=True)
class AugmentConfig:
    """Training augmentations (used only with ``augment=True``).

    flip_lr_prob: probability of a horizontal flip.
    hsv_h: max hue shift as a fraction of the hue circle (+/-).
    hsv_s, hsv_v: max relative saturation / value gain (+/-, e.g. 0.7 -> x0.3..x1.7).
    scale: max relative zoom (+/-); translate: max shift as a fraction of the
    input size (+/-); rotation_deg: max rotation [deg] (+/-; the paper's
    dataset was augmented offline with +/-13 deg, so 0 by default).
    min_box_px: instances whose box is narrower or lower than this [px] after
    the geometric transform are dropped.
    mosaic_prob: probability that an item is a mosaic (YOLOv8-style, but
    without down-scaling, so small bolls keep their size): the input is cut
    into four quadrants at a random point (30-70 % of width and height), each
    filled with a random same-size window of a different augmented item (the
    item itself and three random others); boxes are clipped to their
    quadrant and dropped when less than ``mosaic_min_visible`` of their area
    is left (task 'seg': masks are cut the same way, boxes recomputed).
    mosaic_min_visible: see mosaic_prob (fraction of the box area).
    """

    flip_lr_prob: float = 0.5
    hsv_h: float = 0.015
    hsv_s: float = 0.7
    hsv_v: float = 0.4
    scale: float = 0.2
    translate: float = 0.1
    rotation_deg: float = 0.0
    min_box_px: float = 2.0
    mosaic_prob: float = 0.0
    mosaic_min_visible: float = 0.3

    def __post_init__(self) -> None:
        checks = {
            "flip_lr_prob": 0.0 <= self.flip_lr_prob <= 1.0,
            "hsv_h": 0.0 <= self.hsv_h <= 0.5,
            "hsv_s": 0.0 <= self.hsv_s <= 1.0,
            "hsv_v": 0.0 <= self.hsv_v <= 1.0,
            "scale": 0.0 <= self.scale < 1.0,
            "translate": 0.0 <= self.translate <= 0.5,
            "rotation_deg": 0.0 <= self.rotation_deg <= 180.0,
            "min_box_px": self.min_box_px >= 0.0,
            "mosaic_prob": 0.0 <= self.mosaic_prob <= 1.0,
            "mosaic_min_visible": 0.0 <= self.mosaic_min_visible <= 1.0,
        }
        for name, ok in checks.items():
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and ok):
                raise ValueError(f"AugmentConfig.{name} out of range: {value!r}")


def _random_affine(rng: np.random.Generator, width: int, height: int,
                   cfg: AugmentConfig) -> np.ndarray:
    """A 2x3 matrix: rotate + scale about the image centre, then translate."""
    angle = rng.uniform(-cfg.rotation_deg, cfg.rotation_deg) if cfg.rotation_deg > 0 else 0.0
    s = rng.uniform(1.0 - cfg.scale, 1.0 + cfg.scale) if cfg.scale > 0 else 1.0
    m = cv2.getRotationMatrix2D((width / 2.0, height / 2.0), angle, s)
    if cfg.translate > 0:
        m[0, 2] += rng.uniform(-cfg.translate, cfg.translate) * width
        m[1, 2] += rng.uniform(-cfg.translate, cfg.translate) * height
    return m


def _apply_affine_points(m: np.ndarray, pts: np.ndarray) -> np.ndarray:
    return pts @ m[:, :2].T + m[:, 2]


def _hsv_jitter(rng: np.random.Generator, image_rgb: np.ndarray, cfg: AugmentConfig) -> np.ndarray:
    """Random hue shift and saturation / value gains on a uint8 RGB image."""
    if cfg.hsv_h == 0 and cfg.hsv_s == 0 and cfg.hsv_v == 0:
        return image_rgb
    dh = rng.uniform(-cfg.hsv_h, cfg.hsv_h) * 180.0       # OpenCV hue is 0..179
    gs = rng.uniform(1.0 - cfg.hsv_s, 1.0 + cfg.hsv_s)
    gv = rng.uniform(1.0 - cfg.hsv_v, 1.0 + cfg.hsv_v)
    x = np.arange(256, dtype=np.float64)
    lut_h = np.mod(np.round(x + dh), 180).astype(np.uint8)
    lut_s = np.clip(np.round(x * gs), 0, 255).astype(np.uint8)
    lut_v = np.clip(np.round(x * gv), 0, 255).astype(np.uint8)
    hsv = cv2.cvtColor(image_rgb, cv2.COLOR_RGB2HSV)
    hsv = cv2.merge((cv2.LUT(hsv[..., 0], lut_h), cv2.LUT(hsv[..., 1], lut_s),
                     cv2.LUT(hsv[..., 2], lut_v)))
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)


def _mask_boxes(masks: np.ndarray) -> np.ndarray:
    """Tight (M, 4) boxes [px, pixel edges] of (M, H, W) masks; zeros for empty ones."""
    boxes = np.zeros((masks.shape[0], 4), dtype=np.float32)
    for i, m in enumerate(masks):
        rows = np.flatnonzero(m.any(axis=1))
        cols = np.flatnonzero(m.any(axis=0))
        if rows.size:
            boxes[i] = (cols[0], rows[0], cols[-1] + 1, rows[-1] + 1)
    return boxes


class YoloDataset(Dataset):
    """Images and labels of one split of a YOLO-format dataset (see module docstring).

    root: dataset folder (Roboflow or Ultralytics layout, see yolo_format);
    split: 'train', 'valid' / 'val' or 'test'; task: 'seg' or 'det';
    imgsz: (width, height) of the network input [px]; augment: apply
    :class:`AugmentConfig` jitter; seed: base seed of the augmentations
    (item i of epoch e always gets the same jitter for a given seed, see
    :meth:`set_epoch`); class_names: overrides data.yaml / the paper's names.

    All label files are parsed at construction, so a malformed label raises a
    :class:`yolo_format.LabelFormatError` naming file and line before training.
    """

    def __init__(self, root: str, split: str, task: str, imgsz: Tuple[int, int] = (640, 480),
                 augment: bool = False, seed: int = 0,
                 class_names: Optional[Sequence[str]] = None,
                 augment_config: Optional[AugmentConfig] = None) -> None:
        if task not in yf.TASKS:
            raise ValueError(f"task must be one of {yf.TASKS}, got {task!r}")
        if (not isinstance(imgsz, (tuple, list)) or len(imgsz) != 2
                or not all(isinstance(v, (int, np.integer)) and v > 0 for v in imgsz)):
            raise ValueError(f"imgsz must be (width, height) positive ints, got {imgsz!r}")
        self.root = root
        self.split = split
        self.task = task
        self.width, self.height = int(imgsz[0]), int(imgsz[1])
        self.augment = bool(augment)
        self.seed = int(seed)
        self.augment_config = augment_config if augment_config is not None else AugmentConfig()
        self.class_names = tuple(class_names) if class_names is not None else yf.class_names_for(root, task)
        self.pairs = yf.list_pairs(root, split)
        self.labels = [yf.read_label_file(p.label_path, task, len(self.class_names))
                       for p in self.pairs]
        self.ignores = [yf.read_ignore_instances(p.image_path) if task == "det" else []
                        for p in self.pairs]
        self._epoch = 0

    def set_epoch(self, epoch: int) -> None:
        """Change the augmentation draw (call once per training epoch)."""
        self._epoch = int(epoch)

    def __len__(self) -> int:
        return len(self.pairs)

    def load_image(self, index: int) -> np.ndarray:
        """The original image of item ``index`` as uint8 RGB (H0, W0, 3)."""
        path = self.pairs[index].image_path
        bgr = cv2.imread(path, cv2.IMREAD_COLOR)
        if bgr is None:
            raise yf.LabelFormatError(f"{path}: cannot read image")
        return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)

    def __getitem__(self, index: int):
        if not 0 <= index < len(self.pairs):
            raise IndexError(f"index {index} out of range for {len(self.pairs)} items")
        rng = np.random.default_rng([self.seed, self._epoch, index]) if self.augment else None
        img, classes, boxes, masks, lb, (h0, w0) = self._arrays(index, rng)
        if rng is not None and self.augment_config.mosaic_prob > 0 and len(self.pairs) > 1:
            mrng = np.random.default_rng([self.seed, self._epoch, index, 1])
            if mrng.random() < self.augment_config.mosaic_prob:
                img, classes, boxes, masks = self._mosaic(index, mrng, (img, classes, boxes, masks))
        tensor = torch.from_numpy(np.ascontiguousarray(img.transpose(2, 0, 1))).float().div_(255.0)
        ignored = classes == IGNORE_CLASS
        targets: Dict[str, object] = {
            "classes": torch.from_numpy(classes[~ignored]),
            "boxes_xyxy": torch.from_numpy(boxes[~ignored].astype(np.float32)),
            "ignore_boxes_xyxy": torch.from_numpy(boxes[ignored].astype(np.float32).reshape(-1, 4)),
            "image_path": self.pairs[index].image_path,
            "orig_hw": (h0, w0),
            "letterbox": lb,
        }
        if masks is not None:
            targets["masks"] = torch.from_numpy(masks)
        return tensor, targets

    def _mosaic(self, index: int, rng: np.random.Generator, first):
        """Four items cut into quadrants (see AugmentConfig.mosaic_prob)."""
        w, h = self.width, self.height
        xc = int(round(rng.uniform(0.3, 0.7) * w))
        yc = int(round(rng.uniform(0.3, 0.7) * h))
        quads = [(0, 0, xc, yc), (xc, 0, w, yc), (0, yc, xc, h), (xc, yc, w, h)]
        others = [int(j) for j in rng.integers(0, len(self.pairs), size=3)]
        out_img = np.full((h, w, 3), PAD_VALUE, dtype=np.uint8)
        out_cls, out_boxes, out_masks = [], [], []
        min_vis, min_px = self.augment_config.mosaic_min_visible, self.augment_config.min_box_px
        for q, (x0, y0, x1, y1) in enumerate(quads):
            if q == 0:
                img, cls, boxes, masks = first
            else:
                j = others[q - 1]
                img, cls, boxes, masks, _, _ = self._arrays(j, np.random.default_rng(
                    [self.seed, self._epoch, index, 2 + q, j]))
            qw, qh = x1 - x0, y1 - y0
            if qw <= 0 or qh <= 0:
                continue
            ox = int(rng.integers(0, w - qw + 1))       # window of the source item
            oy = int(rng.integers(0, h - qh + 1))
            out_img[y0:y1, x0:x1] = img[oy:oy + qh, ox:ox + qw]
            if masks is not None:
                cut = np.zeros((len(masks), h, w), dtype=np.uint8)
                cut[:, y0:y1, x0:x1] = masks[:, oy:oy + qh, ox:ox + qw]
                b = _mask_boxes(cut)
                keep = cut.reshape(len(cut), h * w).any(axis=1)
            else:
                b = boxes.astype(np.float64) + [x0 - ox, y0 - oy, x0 - ox, y0 - oy]
                area0 = np.prod(b[:, 2:] - b[:, :2], axis=1)
                b[:, [0, 2]] = b[:, [0, 2]].clip(x0, x1)
                b[:, [1, 3]] = b[:, [1, 3]].clip(y0, y1)
                wh = b[:, 2:] - b[:, :2]
                keep = (wh[:, 0] > min_px) & (wh[:, 1] > min_px) & \
                    (wh[:, 0] * wh[:, 1] >= min_vis * np.maximum(area0, 1e-9))
                keep |= (cls == IGNORE_CLASS) & (wh[:, 0] > 0) & (wh[:, 1] > 0)
                cut = None
            out_cls.append(cls[keep])
            out_boxes.append(b[keep].astype(np.float32))
            if cut is not None:
                out_masks.append(cut[keep])
        classes = np.concatenate(out_cls) if out_cls else np.zeros(0, np.int64)
        boxes = np.concatenate(out_boxes).reshape(-1, 4) if out_boxes else np.zeros((0, 4), np.float32)
        masks = (np.concatenate(out_masks) if out_masks else np.zeros((0, h, w), np.uint8)) \
            if first[3] is not None else None
        return out_img, classes, boxes, masks

    def _arrays(self, index: int, rng: Optional[np.random.Generator]):
        """(image uint8 (H, W, 3), classes, boxes (M, 4) [px], masks or None, letterbox, (H0, W0))
        of item ``index``, augmented with ``rng`` (None: no augmentation)."""
        image = self.load_image(index)
        h0, w0 = image.shape[:2]
        img, lb = letterbox(image, self.width, self.height)
        affine = lb.affine()                     # original px -> input px
        instances = self.labels[index] + self.ignores[index]
        classes = np.array([inst.class_id for inst in self.labels[index]]
                           + [IGNORE_CLASS] * len(self.ignores[index]), dtype=np.int64)
        flip = False
        if rng is not None:  # (the draws keep their order: same jitter as before mosaics existed)
            cfg = self.augment_config
            geo = _random_affine(rng, self.width, self.height, cfg)
            img = cv2.warpAffine(img, geo, (self.width, self.height), flags=cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_CONSTANT, borderValue=(PAD_VALUE,) * 3)
            affine = np.vstack([geo, [0, 0, 1]]) @ np.vstack([affine, [0, 0, 1]])
            affine = affine[:2]
            img = _hsv_jitter(rng, img, cfg)
            flip = rng.random() < cfg.flip_lr_prob
            min_px = cfg.min_box_px
        else:
            min_px = 0.0

        if self.task == "seg":
            masks = np.zeros((len(instances), self.height, self.width), dtype=np.uint8)
            for i, inst in enumerate(instances):
                poly = inst.polygon_px(w0, h0)
                if poly is None:  # cannot happen for 'seg' labels; kept for safety
                    continue
                masks[i] = yf.polygon_to_mask(_apply_affine_points(affine, poly), self.height, self.width)
            boxes = _mask_boxes(masks)
        else:
            masks = None
            boxes = np.zeros((len(instances), 4), dtype=np.float32)
            for i, inst in enumerate(instances):
                x1, y1, x2, y2 = inst.box_xyxy_px(w0, h0)
                corners = np.array([[x1, y1], [x2, y1], [x2, y2], [x1, y2]])
                c = _apply_affine_points(affine, corners)
                boxes[i] = (c[:, 0].min(), c[:, 1].min(), c[:, 0].max(), c[:, 1].max())
            boxes[:, [0, 2]] = boxes[:, [0, 2]].clip(0, self.width)
            boxes[:, [1, 3]] = boxes[:, [1, 3]].clip(0, self.height)

        wh = boxes[:, 2:] - boxes[:, :2]
        keep = (wh[:, 0] > max(min_px, 0.0)) & (wh[:, 1] > max(min_px, 0.0))
        keep |= (classes == IGNORE_CLASS) & (wh[:, 0] > 0) & (wh[:, 1] > 0)
        if masks is not None:
            keep &= masks.reshape(len(masks), self.height * self.width).any(axis=1)
        boxes, classes = boxes[keep], classes[keep]
        if masks is not None:
            masks = masks[keep]

        if flip:
            img = np.ascontiguousarray(img[:, ::-1])
            boxes = boxes.copy()
            boxes[:, [0, 2]] = self.width - boxes[:, [2, 0]]
            if masks is not None:
                masks = np.ascontiguousarray(masks[:, :, ::-1])

        return img, classes, boxes, masks, lb, (h0, w0)


def collate(batch: List[Tuple[torch.Tensor, Dict[str, object]]]):
    """Stack a list of dataset items for a DataLoader.

    Returns ``(images, targets)``: images (B, 3, H, W) float32; targets a dict
    with the instances of all images concatenated (Ultralytics' convention):
    ``batch_idx`` (N,) int64 (which image), ``classes`` (N,) int64,
    ``boxes_xyxy`` (N, 4) float32 [px], ``masks`` (N, H, W) uint8 (seg only),
    ``ignore_batch_idx`` (K,) int64 and ``ignore_boxes_xyxy`` (K, 4) float32 [px],
    plus per-image lists ``image_paths``, ``orig_hw``, ``letterbox``.
    """
    if not batch:
        raise ValueError("collate: empty batch")
    images = torch.stack([item[0] for item in batch], dim=0)
    targets = [item[1] for item in batch]
    out: Dict[str, object] = {
        "batch_idx": torch.cat([torch.full((len(t["classes"]),), i, dtype=torch.int64)
                                for i, t in enumerate(targets)]),
        "classes": torch.cat([t["classes"] for t in targets]),
        "boxes_xyxy": torch.cat([t["boxes_xyxy"] for t in targets]).reshape(-1, 4),
        "ignore_batch_idx": torch.cat([torch.full((len(t["ignore_boxes_xyxy"]),), i, dtype=torch.int64)
                                       for i, t in enumerate(targets)]),
        "ignore_boxes_xyxy": torch.cat([t["ignore_boxes_xyxy"] for t in targets]).reshape(-1, 4),
        "image_paths": [t["image_path"] for t in targets],
        "orig_hw": [t["orig_hw"] for t in targets],
        "letterbox": [t["letterbox"] for t in targets],
    }
    if "masks" in targets[0]:
        h, w = images.shape[2:]
        out["masks"] = torch.cat([t["masks"].reshape(-1, h, w) for t in targets])
    return images, out
