"""How well a mask can be drawn at a coarse resolution: an upper bound for mask mAP50.

Why: the scene segmenter predicts its masks as a combination of prototype
maps at 1/4 of its input, i.e. 1/8 of a 640x480 frame at the default 320x256
input, so thin structures (defoliated stems, far plants a few pixels wide)
cannot be drawn exactly whatever the training. :func:`coarse_mask_iou` gives
the best IoU any mask made at 1/``factor`` resolution can reach against the
labelled mask (area-averaged down, bilinear up, best of a few thresholds: an
optimistic oracle), and :func:`fraction_reachable` the share of masks that
reach an IoU threshold: mask AP50 of that class cannot exceed it by much.
"""
from __future__ import annotations

from typing import Iterable, Sequence

import cv2
import numpy as np


def coarse_mask_iou(mask: np.ndarray, factor: int,
                    thresholds: Sequence[float] = (0.2, 0.3, 0.4, 0.5, 0.6)) -> float:
    """Best IoU of a 1/factor-resolution reconstruction of the (H, W) bool mask (nan if empty)."""
    m = np.asarray(mask, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask must be (H, W), got shape {m.shape}")
    if not isinstance(factor, (int, np.integer)) or factor < 1:
        raise ValueError(f"factor must be a positive int, got {factor!r}")
    if not m.any():
        return float("nan")
    h, w = m.shape
    small = cv2.resize(m.astype(np.float32), (max(1, w // factor), max(1, h // factor)),
                       interpolation=cv2.INTER_AREA)
    up = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
    best = 0.0
    for t in thresholds:
        p = up > t
        best = max(best, float(np.count_nonzero(p & m)) / float(np.count_nonzero(p | m)))
    return best


def fraction_reachable(masks: Iterable[np.ndarray], factor: int, iou_threshold: float = 0.5) -> float:
    """Share of the non-empty masks whose :func:`coarse_mask_iou` reaches iou_threshold."""
    ious = [coarse_mask_iou(m, factor) for m in masks]
    ious = [v for v in ious if not np.isnan(v)]
    if not ious:
        raise ValueError("no non-empty masks")
    return float(np.mean(np.array(ious) >= iou_threshold))
