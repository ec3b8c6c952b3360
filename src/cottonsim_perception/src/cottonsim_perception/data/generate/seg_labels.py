"""Scene-segmentation labels: class masks of a rendered semantic image -> YOLO polygons.

Classes (the original CottonSim dataset's order): 0 cotton plants (plant and
boll pixels), 1 ground, 2 sky. Each connected region of a class becomes one
polygon with its holes cut in by zero-width bridges (``mask_to_label_polygons``);
by default the regions of a class are then joined into one label line per
class (``LabelConfig.seg_instances``). ``class_ious`` checks the round trip
(polygons rasterized back against the masks). Polygons are in pixel-edge
coordinates as in ``yolo_format``. No ROS imports.
"""
from __future__ import annotations

import math
from typing import Dict, List, Optional, Sequence

import cv2
import numpy as np
from scipy.spatial import cKDTree

from cottonsim_perception.data import yolo_format as yf
from cottonsim_world.farm.model import SemanticClass

from .config import LabelConfig

#: Segmentation class ids (the original CottonSim dataset's order).
SEG_PLANT, SEG_GROUND, SEG_SKY = 0, 1, 2


def _bridge_holes(outer: np.ndarray, holes: Sequence[np.ndarray]) -> np.ndarray:
    """One polygon = ``outer`` with each hole joined in by a zero-width bridge.

    Each hole is cut open at its vertex nearest to the outline and spliced in
    after that outline vertex (outline ... o_i, h_j, h_j+1, ..., h_j, o_i ...).
    Even-odd filling of the result is the outer region minus the holes: a
    bridge's two coincident edges toggle the fill twice, i.e. not at all,
    also where a bridge passes over another hole.
    """
    poly = np.asarray(outer, dtype=np.float64)
    if not holes:
        return poly
    hs = [np.asarray(hole, dtype=np.float64) for hole in holes]
    dist, idx = cKDTree(poly).query(np.concatenate(hs))      # one query for all hole vertices
    splice: Dict[int, List[np.ndarray]] = {}
    start = 0
    for h in hs:
        seg = slice(start, start + len(h))
        start += len(h)
        j = int(np.argmin(dist[seg]))
        ring = np.concatenate([h[j:], h[:j + 1]])     # starts and ends at the bridge vertex h[j]
        splice.setdefault(int(idx[seg][j]), []).append(ring)
    parts, start = [], 0
    for i in sorted(splice):
        parts.append(poly[start:i + 1])
        for ring in splice[i]:
            parts.append(ring)
            parts.append(poly[i:i + 1])               # back on the outline after each hole
        start = i + 1
    parts.append(poly[start:])
    return np.concatenate(parts)


def _holes(mask: np.ndarray) -> np.ndarray:
    """Background pixels not 4-connected to the image border (pockets enclosed by the mask)."""
    h, w = mask.shape
    bg = np.zeros((h + 2, w + 2), dtype=np.uint8)
    bg[1:-1, 1:-1] = ~mask
    bg[0, :] = bg[-1, :] = 1
    bg[:, 0] = bg[:, -1] = 1
    # flood the background from the frame; what stays 1 is enclosed
    cv2.floodFill(bg, None, (0, 0), 0, flags=4)
    return bg[1:-1, 1:-1].astype(bool)


def mask_to_label_polygons(mask: np.ndarray, epsilon_px: float = 0.3, min_area_px: float = 0.1,
                           min_hole_area_px: Optional[float] = None) -> List[np.ndarray]:
    """YOLO polygons [px, pixel edges] of a class mask: one per connected region, holes cut in.

    The 8-connected regions are traced with ``yolo_format.mask_to_polygons``
    (Douglas-Peucker ``epsilon_px``; regions whose polygon area is below
    ``min_area_px`` [px^2] are skipped). The holes (background pockets
    enclosed by a region) are traced the same way (skipped below
    ``min_hole_area_px``, default ``min_area_px``) and joined to the outline
    of the region around them by zero-width bridges (``_bridge_holes``),
    because a YOLO label line cannot hold a hole. An island inside a hole is
    a region (and polygon) of its own. ``yolo_format.polygon_to_mask`` of the
    polygons then reproduces the mask up to the tolerance and the skipped specks.
    """
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask_to_label_polygons: expected an (H, W) mask, got shape {m.shape}")
    m = m.astype(bool)
    if not m.any():
        return []
    hole_area = min_area_px if min_hole_area_px is None else min_hole_area_px
    holes_mask = _holes(m)
    # regions inside a hole (islands) are not outer contours of ``m``: trace them recursively
    islands = m & _holes(holes_mask) if holes_mask.any() else None
    inner = (mask_to_label_polygons(islands, epsilon_px, min_area_px, min_hole_area_px)
             if islands is not None and islands.any() else [])
    outers = yf.mask_to_polygons(m, epsilon_px, min_area_px)
    if not holes_mask.any():
        return outers
    h, w = m.shape
    _, lab = cv2.connectedComponents(m.astype(np.uint8), connectivity=8)

    def region_at(px: float, py: float) -> int:
        return int(lab[min(max(int(py), 0), h - 1), min(max(int(px), 0), w - 1)])

    # outline vertices lie a quarter pixel inside their region's boundary pixels
    by_region = {region_at(*p[0]): k for k, p in enumerate(outers)}
    hole_lists: Dict[int, List[np.ndarray]] = {}
    for hole in yf.mask_to_polygons(holes_mask, epsilon_px, hole_area):
        # the pixel above the hole's top-most vertex belongs to the region around it
        top = hole[int(np.argmin(hole[:, 1]))]
        col = min(max(int(top[0]), 0), w - 1)
        row = int(top[1])
        while row >= 0 and not m[row, col]:
            row -= 1
        if row < 0:
            continue                                  # cannot happen for a true hole
        k = by_region.get(int(lab[row, col]))
        if k is not None:
            hole_lists.setdefault(k, []).append(hole)
    return [_bridge_holes(p, hole_lists[k]) if k in hole_lists else p for k, p in enumerate(outers)] + inner


def segmentation_masks(semantic: np.ndarray) -> Dict[int, np.ndarray]:
    """Per segmentation class id, its (H, W) bool mask (plant includes boll pixels)."""
    sem = np.asarray(semantic)
    return {SEG_PLANT: (sem == SemanticClass.PLANT) | (sem == SemanticClass.BOLL),
            SEG_GROUND: sem == SemanticClass.GROUND,
            SEG_SKY: sem == SemanticClass.SKY}


def segmentation_instances(semantic: np.ndarray, config: LabelConfig = LabelConfig()) -> List[yf.LabelInstance]:
    """Scene-segmentation labels of one semantic image, normalised to [0, 1]."""
    sem = np.asarray(semantic)
    if sem.ndim != 2:
        raise ValueError(f"semantic must be an (H, W) image, got shape {sem.shape}")
    h, w = sem.shape
    scale = np.array([w, h], dtype=np.float64)
    out = []
    for cls, mask in segmentation_masks(sem).items():
        for poly in mask_to_label_polygons(mask, config.polygon_epsilon_px, config.min_region_area_px,
                                           config.min_hole_area_px):
            norm = np.clip(poly / scale, 0.0, 1.0)
            out.append(yf.LabelInstance(cls, yf.polygon_bbox_cxcywh(norm), norm))
    if config.seg_instances == "class":
        out = yf.merge_instances_per_class(out)
    return out


def rasterize_instances(instances: Sequence[yf.LabelInstance], height: int, width: int,
                        num_classes: int = 3) -> np.ndarray:
    """(num_classes, H, W) bool: per class, the union of its polygons (boxes for box labels).

    Same pixel rule as ``yolo_format.polygon_to_mask`` (pixel centre inside,
    even-odd), evaluated in each polygon's bounding box for speed.
    """
    out = np.zeros((num_classes, height, width), dtype=bool)
    for inst in instances:
        if not 0 <= inst.class_id < num_classes:
            raise ValueError(f"class id {inst.class_id} outside [0, {num_classes})")
        poly = inst.polygon_px(width, height)
        if poly is None:
            x1, y1, x2, y2 = inst.box_xyxy_px(width, height)
            poly = np.array([[x1, y1], [x2, y1], [x2, y2], [x1, y2]])
        c0 = max(0, int(math.floor(poly[:, 0].min())) - 1)
        r0 = max(0, int(math.floor(poly[:, 1].min())) - 1)
        c1 = min(width, int(math.ceil(poly[:, 0].max())) + 1)
        r1 = min(height, int(math.ceil(poly[:, 1].max())) + 1)
        if c1 <= c0 or r1 <= r0:
            continue
        out[inst.class_id, r0:r1, c0:c1] |= yf.polygon_to_mask(poly - [c0, r0], r1 - r0, c1 - c0)
    return out


def class_ious(semantic: np.ndarray, instances: Sequence[yf.LabelInstance]) -> Dict[int, float]:
    """Per segmentation class: IoU of the rasterised labels with the ground-truth mask
    (nan for a class absent from both)."""
    sem = np.asarray(semantic)
    h, w = sem.shape
    drawn = rasterize_instances(instances, h, w, 3)
    out = {}
    for cls, mask in segmentation_masks(sem).items():
        union = np.count_nonzero(mask | drawn[cls])
        out[cls] = float(np.count_nonzero(mask & drawn[cls]) / union) if union else float("nan")
    return out
