"""Pure helpers of the Cotton-Eye nodes: label images, oracle boxes, boll 3-D positions.

Why a core module: the ROS nodes in ``cottonsim_perception.ros`` only turn
messages into arrays and back; everything that can be wrong numerically
(which pixels belong to a box, how a depth point projects, what 'in reach'
means) lives here and is unit-tested without a ROS master.

* :func:`label_image_from_masks` / :func:`label_image_from_detections`: one
  mono8 label image (``SemanticClass`` ids, 255 = unlabelled) from per-class
  masks or from a segmentation network's instances.
* :func:`colorize_labels`: an RGB overlay of a label image for rviz.
* :func:`boxes_from_semantic`: the ground-truth 'detector' used before the
  boll network is trained: one box per connected component of boll pixels.
* :func:`localize_boxes`: the 3-D position of each box from the camera's
  depth point cloud (median of the cloud points that project into the box).
* :func:`points_within_reach`: the UR5e reach test (points moved into the
  arm frame with ``cottonsim_common.transforms.transform_points``).

Pixel convention (as in ``types``): pixel-edge coordinates, x right, y
down; the pixel in column j covers x in [j, j + 1). CameraInfo's principal
point is in pixel-index coordinates (the pixel (0, 0) is centred at (0, 0)),
so a point projects to the edge coordinate u = fx * x / z + cx + 0.5.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Optional, Sequence, Tuple

import numpy as np

from .types import Detections

#: label value of pixels that no class claims
UNLABELLED = 255
#: SemanticClass ids (cottonsim_world.farm.model) used in label images
PLANT, GROUND, SKY, BOLL = 0, 1, 2, 3
#: overlay colours (RGB) per label id
LABEL_COLOURS = {PLANT: (40, 170, 40), GROUND: (150, 95, 45), SKY: (70, 150, 255), BOLL: (255, 255, 255)}


def label_image_from_masks(masks: Mapping[int, np.ndarray], shape: Tuple[int, int],
                           order: Sequence[int] = (GROUND, SKY, PLANT, BOLL)) -> np.ndarray:
    """(H, W) uint8 label image from class id -> (H, W) bool masks.

    Later classes in ``order`` overwrite earlier ones where masks overlap
    (plants in front of ground and sky, bolls on plants); classes missing
    from ``masks`` are skipped; unclaimed pixels are ``UNLABELLED``.
    Raises ValueError for a mask of another shape.
    """
    h, w = int(shape[0]), int(shape[1])
    labels = np.full((h, w), UNLABELLED, dtype=np.uint8)
    for cls in order:
        m = masks.get(cls)
        if m is None:
            continue
        m = np.asarray(m, dtype=bool)
        if m.shape != (h, w):
            raise ValueError(f"mask of class {cls} has shape {m.shape}, expected {(h, w)}")
        labels[m] = cls
    return labels


def label_image_from_detections(detections: Detections, shape: Tuple[int, int],
                                class_ids: Sequence[int] = (PLANT, GROUND, SKY)) -> np.ndarray:
    """Label image from a segmentation network's instances.

    ``class_ids[k]`` is the label written for the network's class k (the
    scene network's classes are cotton_plant, ground, sky = SemanticClass
    0, 1, 2). Instances are painted lowest score first, so where two
    instance masks overlap the more confident one wins. Raises ValueError for
    box-only detections or a class id without a label.
    """
    h, w = int(shape[0]), int(shape[1])
    if detections.masks is None:
        raise ValueError("label_image_from_detections needs segmentation detections (masks is None)")
    labels = np.full((h, w), UNLABELLED, dtype=np.uint8)
    if len(detections) == 0:
        return labels
    if detections.masks.shape[1:] != (h, w):
        raise ValueError(f"masks are {detections.masks.shape[1:]}, expected {(h, w)}")
    for i in np.argsort(detections.scores, kind="stable"):
        c = int(detections.classes[i])
        if not 0 <= c < len(class_ids):
            raise ValueError(f"network class {c} has no label (class_ids has {len(class_ids)} entries)")
        labels[detections.masks[i]] = int(class_ids[c])
    return labels


def colorize_labels(labels: np.ndarray, image_rgb: Optional[np.ndarray] = None,
                     alpha: float = 0.5) -> np.ndarray:
    """(H, W, 3) uint8 RGB: the label colours, blended over ``image_rgb`` when given."""
    labels = np.asarray(labels)
    if labels.ndim != 2:
        raise ValueError(f"labels must be (H, W), got shape {labels.shape}")
    lut = np.zeros((256, 3), dtype=np.float32)
    for cls, colour in LABEL_COLOURS.items():
        lut[cls] = colour
    colour = lut[labels]
    if image_rgb is None:
        return colour.astype(np.uint8)
    image_rgb = np.asarray(image_rgb)
    if image_rgb.shape != labels.shape + (3,):
        raise ValueError(f"image is {image_rgb.shape}, labels are {labels.shape}")
    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"alpha must be in [0, 1], got {alpha}")
    labelled = (labels != UNLABELLED)[..., None]
    out = np.where(labelled, (1.0 - alpha) * image_rgb + alpha * colour, image_rgb)
    return np.clip(out, 0, 255).astype(np.uint8)


def boxes_from_semantic(semantic: np.ndarray, class_id: int = BOLL,
                        min_area_px: int = 4) -> np.ndarray:
    """(N, 4) float32 boxes (x_min, y_min, x_max, y_max) [px, pixel edges] of the
    8-connected components of ``class_id`` in a semantic image with at least
    ``min_area_px`` pixels, largest first. Touching bolls merge into one box
    (what a detector trained on such labels would also tend to do).
    """
    import cv2

    sem = np.asarray(semantic)
    if sem.ndim != 2 or sem.size == 0:
        raise ValueError(f"semantic image must be a non-empty (H, W) array, got shape {sem.shape}")
    if isinstance(min_area_px, bool) or not isinstance(min_area_px, (int, np.integer)) or min_area_px < 1:
        raise ValueError(f"min_area_px must be an int >= 1, got {min_area_px!r}")
    mask = (sem == class_id).astype(np.uint8)
    count, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    rows = []
    for i in range(1, count):                        # 0 is the background
        x, y, w, h, area = (int(v) for v in stats[i])
        if area >= min_area_px:
            rows.append((area, (x, y, x + w, y + h)))
    rows.sort(key=lambda r: -r[0])
    if not rows:
        return np.zeros((0, 4), dtype=np.float32)
    return np.array([b for _, b in rows], dtype=np.float32)


@dataclass(frozen=True)
class BollLocalizationConfig:
    """Parameters of :func:`localize_boxes`.

    min_points: a box needs at least this many cloud points inside it to get
        a position (fewer: no position) [-].
    box_shrink_fraction: the box is shrunk by this fraction of its width /
        height on each side before points are collected, so the median is
        not pulled by leaves or ground at the box's corners [-] (0 = whole box).
    min_depth_m / max_depth_m: cloud points outside this depth range (z in
        the optical frame) are ignored [m] (D435: 0.105 m minimum).
    front_depth_m: only points at most this far behind the box's near
        surface (its 10th-percentile depth) are used [m]; a boll is the
        nearest thing in its box, and the points that fall into the box
        through gaps (leaves, the next row, the ground behind) would pull a
        plain median away from it (measured: bolls placed between two rows).
    surface_to_centre: the camera sees a boll's near surface, so the median of its points lies about
        0.7 radius in front of its centre (2 cm for a 6 cm boll, as much as a vacuum nozzle's capture
        radius). True: the median point is moved along its viewing ray to the depth of the near
        surface (the 10th-percentile depth) plus the boll's radius, taken as a quarter of the box's
        metric width + height at that depth. False: the median of the surface points.
    lint_colour: with the camera's colour image, only the points whose pixel looks like cotton lint
        (every channel at least ``lint_min_value``, channels at most ``lint_max_chroma`` apart: bright
        and grey-white; leaves are green, soil brown, sky blue) count, when at least min_points of the
        box do; a leaf in front of part of a boll otherwise becomes the box's front surface (a
        detections harvest of row 1, seed 0, first 909 s of sim time: 'ok' 83 -> 132,
        'capture_missed' 96 -> 28).
    lint_min_value, lint_max_chroma: the lint test's thresholds [0-255].
    """

    min_points: int = 3
    box_shrink_fraction: float = 0.15
    min_depth_m: float = 0.105
    max_depth_m: float = 4.0
    front_depth_m: float = 0.15
    surface_to_centre: bool = True
    lint_colour: bool = True
    lint_min_value: int = 150
    lint_max_chroma: int = 60

    def __post_init__(self) -> None:
        if not isinstance(self.lint_colour, bool):
            raise ValueError(f"BollLocalizationConfig.lint_colour must be true or false, got {self.lint_colour!r}")
        for name in ("lint_min_value", "lint_max_chroma"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 0 <= v <= 255:
                raise ValueError(f"BollLocalizationConfig.{name} must be an int in [0, 255], got {v!r}")
        if not isinstance(self.surface_to_centre, bool):
            raise ValueError(f"BollLocalizationConfig.surface_to_centre must be true or false, "
                             f"got {self.surface_to_centre!r}")
        if isinstance(self.min_points, bool) or not isinstance(self.min_points, (int, np.integer)) \
                or self.min_points < 1:
            raise ValueError(f"BollLocalizationConfig.min_points must be an int >= 1, got {self.min_points!r}")
        if not (isinstance(self.box_shrink_fraction, (int, float)) and 0.0 <= self.box_shrink_fraction < 0.5):
            raise ValueError("BollLocalizationConfig.box_shrink_fraction must be in [0, 0.5), "
                             f"got {self.box_shrink_fraction!r}")
        for name in ("min_depth_m", "max_depth_m", "front_depth_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"BollLocalizationConfig.{name} must be a finite number >= 0, got {v!r}")
        if self.max_depth_m <= self.min_depth_m:
            raise ValueError("BollLocalizationConfig.max_depth_m must be > min_depth_m")


def project_points(xyz: np.ndarray, fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """(N, 2) pixel-edge coordinates (u, v) of optical-frame points (z > 0 assumed).

    fx, fy, cx, cy: CameraInfo K entries [px] (principal point in
    pixel-index coordinates, see the module docstring).
    """
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = fx * xyz[:, 0] / xyz[:, 2] + cx + 0.5
        v = fy * xyz[:, 1] / xyz[:, 2] + cy + 0.5
    return np.stack([u, v], axis=1)


def localize_boxes(boxes_xyxy: np.ndarray, cloud_xyz: np.ndarray, k: Sequence[float],
                   config: BollLocalizationConfig = BollLocalizationConfig(),
                   image_rgb: Optional[np.ndarray] = None) -> Tuple[np.ndarray, np.ndarray]:
    """3-D position of each box: the per-axis median of the cloud points inside it.

    boxes_xyxy: (N, 4) [px, pixel edges]; cloud_xyz: (M, 3) points in the
    camera's optical frame [m] (NaN rows are ignored; any order: points are
    matched to boxes by projecting them with ``k``, so a decimated or
    unorganised cloud works as well as an organised one); k: the 3x3 camera
    matrix (9 numbers, row-major, CameraInfo.K).
    Only the points near the box's front surface count (``front_depth_m``); their median is moved
    from the surface to the boll's centre (``surface_to_centre``). With ``config.lint_colour`` and the
    colour image the points project into ((H, W, 3) uint8 RGB), only lint-coloured points count.
    Returns (positions (N, 3) float64 [m] in the optical frame, NaN where
    a box holds fewer than ``min_points`` points; valid (N,) bool).
    """
    boxes = np.asarray(boxes_xyxy, dtype=np.float64)
    if boxes.ndim != 2 or boxes.shape[1] != 4:
        raise ValueError(f"boxes_xyxy must be (N, 4), got shape {boxes.shape}")
    kk = np.asarray(k, dtype=np.float64).reshape(-1)
    if kk.size != 9 or not np.all(np.isfinite(kk)) or kk[0] <= 0 or kk[4] <= 0:
        raise ValueError("k must be a 3x3 camera matrix with positive focal lengths (CameraInfo.K)")
    pts = np.asarray(cloud_xyz, dtype=np.float64).reshape(-1, 3)
    n = boxes.shape[0]
    positions = np.full((n, 3), np.nan)
    valid = np.zeros(n, dtype=bool)
    if n == 0 or pts.shape[0] == 0:
        return positions, valid
    keep = np.all(np.isfinite(pts), axis=1) & (pts[:, 2] >= config.min_depth_m) & (pts[:, 2] <= config.max_depth_m)
    pts = pts[keep]
    uv = project_points(pts, kk[0], kk[4], kk[2], kk[5])
    lint = _lint_points(uv, image_rgb, config) if config.lint_colour and image_rgb is not None else None
    s = config.box_shrink_fraction
    for i, (x0, y0, x1, y1) in enumerate(boxes):
        dx, dy = s * (x1 - x0), s * (y1 - y0)
        inside = (uv[:, 0] >= x0 + dx) & (uv[:, 0] < x1 - dx) & (uv[:, 1] >= y0 + dy) & (uv[:, 1] < y1 - dy)
        if int(inside.sum()) < config.min_points:
            continue
        if lint is not None and int((inside & lint).sum()) >= config.min_points:
            inside &= lint
        box_pts = pts[inside]
        front_z = np.percentile(box_pts[:, 2], 10.0)
        near = box_pts[:, 2] <= front_z + config.front_depth_m
        if int(near.sum()) >= config.min_points:
            median = np.median(box_pts[near], axis=0)
            if config.surface_to_centre and median[2] > 0.0:
                radius = 0.25 * ((x1 - x0) / kk[0] + (y1 - y0) / kk[4]) * front_z
                median = median * ((front_z + radius) / median[2])
            positions[i] = median
            valid[i] = True
    return positions, valid


def _lint_points(uv: np.ndarray, image_rgb: np.ndarray, config: BollLocalizationConfig) -> np.ndarray:
    """(M,) bool: the point's pixel (uv: pixel edges) in the image looks like cotton lint (outside: False)."""
    img = np.asarray(image_rgb)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"image_rgb must be (H, W, 3), got shape {img.shape}")
    h, w = img.shape[:2]
    col, row = np.floor(uv[:, 0]).astype(np.int64), np.floor(uv[:, 1]).astype(np.int64)
    on = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    rgb = np.zeros((len(uv), 3), dtype=np.int32)
    rgb[on] = img[row[on], col[on]]
    lo, hi = rgb.min(axis=1), rgb.max(axis=1)
    return on & (lo >= config.lint_min_value) & (hi - lo <= config.lint_max_chroma)


def points_within_reach(points_arm: np.ndarray, reach_m: float) -> np.ndarray:
    """(N,) bool: the point (in the arm base frame) lies within ``reach_m`` of its origin; NaN -> False."""
    if not (isinstance(reach_m, (int, float)) and math.isfinite(reach_m) and reach_m > 0):
        raise ValueError(f"reach_m must be a finite number > 0, got {reach_m!r}")
    pts = np.asarray(points_arm, dtype=np.float64).reshape(-1, 3)
    with np.errstate(invalid="ignore"):
        return np.linalg.norm(pts, axis=1) <= reach_m
