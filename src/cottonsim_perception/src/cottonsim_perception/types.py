"""Result types of the Cotton-Eye networks: the contract with evaluation code.

``Detections`` is what :class:`cottonsim_perception.inference.Predictor`
returns for one image; ``GroundTruth`` is the same shape of data read from a
labelled dataset. Both are in *original image pixels* (the letterbox used by
the network is already undone), so metrics never need to know the network's
input size.

Coordinates: ``boxes_xyxy`` rows are (x_min, y_min, x_max, y_max) [px], x to
the right, y down, pixel edges (a box covering the whole W x H image is
(0, 0, W, H)). Masks are boolean images of the original size (H, W).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np


def _check_common(name: str, boxes: np.ndarray, classes: np.ndarray,
                  masks: Optional[np.ndarray]) -> int:
    """Validate box / class / mask arrays shared by both types; returns N."""
    if not isinstance(boxes, np.ndarray) or boxes.ndim != 2 or boxes.shape[1] != 4:
        raise ValueError(f"{name}.boxes_xyxy must be an (N, 4) array, got "
                         f"{getattr(boxes, 'shape', type(boxes))}")
    n = boxes.shape[0]
    if not np.all(np.isfinite(boxes)):
        raise ValueError(f"{name}.boxes_xyxy contains NaN or inf")
    if not isinstance(classes, np.ndarray) or classes.shape != (n,):
        raise ValueError(f"{name}.classes must have shape ({n},), got "
                         f"{getattr(classes, 'shape', type(classes))}")
    if classes.dtype != np.int64:
        raise ValueError(f"{name}.classes must be int64, got {classes.dtype}")
    if masks is not None:
        if not isinstance(masks, np.ndarray) or masks.ndim != 3 or masks.shape[0] != n:
            raise ValueError(f"{name}.masks must be (N={n}, H, W) or None, got "
                             f"{getattr(masks, 'shape', type(masks))}")
        if masks.dtype != np.bool_:
            raise ValueError(f"{name}.masks must be bool, got {masks.dtype}")
    return n


@dataclass(frozen=True)
class Detections:
    """Predicted instances of one image, in original image pixels.

    boxes_xyxy: (N, 4) float32 [px]; scores: (N,) float32 in [0, 1];
    classes: (N,) int64 class ids; masks: (N, H, W) bool of the original
    image size for segmentation models, None for box-only detectors.
    Rows are sorted by descending score.
    """

    boxes_xyxy: np.ndarray
    scores: np.ndarray
    classes: np.ndarray
    masks: Optional[np.ndarray] = None

    def __post_init__(self) -> None:
        n = _check_common("Detections", self.boxes_xyxy, self.classes, self.masks)
        if self.boxes_xyxy.dtype != np.float32:
            raise ValueError(f"Detections.boxes_xyxy must be float32, got {self.boxes_xyxy.dtype}")
        if not isinstance(self.scores, np.ndarray) or self.scores.shape != (n,):
            raise ValueError(f"Detections.scores must have shape ({n},)")
        if self.scores.dtype != np.float32:
            raise ValueError(f"Detections.scores must be float32, got {self.scores.dtype}")

    def __len__(self) -> int:
        return int(self.boxes_xyxy.shape[0])

    @staticmethod
    def empty(image_shape: Optional[tuple] = None) -> "Detections":
        """No detections; with ``image_shape`` (H, W) an empty (0, H, W) mask array."""
        masks = None
        if image_shape is not None:
            masks = np.zeros((0, int(image_shape[0]), int(image_shape[1])), dtype=bool)
        return Detections(np.zeros((0, 4), np.float32), np.zeros((0,), np.float32),
                          np.zeros((0,), np.int64), masks)


@dataclass(frozen=True)
class GroundTruth:
    """Labelled instances of one image, in original image pixels.

    boxes_xyxy: (M, 4) float [px]; classes: (M,) int64; masks: (M, H, W)
    bool of the original image size (segmentation labels) or None;
    ignore_boxes_xyxy: (K, 4) float [px] don't-care regions (objects outside
    the labelling rules, e.g. bolls beyond the working range; see
    ``yolo_format.ignore_path_for``) or None: an unmatched prediction lying
    on one is neither a true nor a false positive.
    """

    boxes_xyxy: np.ndarray
    classes: np.ndarray
    masks: Optional[np.ndarray] = None
    ignore_boxes_xyxy: Optional[np.ndarray] = None

    def __post_init__(self) -> None:
        _check_common("GroundTruth", self.boxes_xyxy, self.classes, self.masks)
        ign = self.ignore_boxes_xyxy
        if ign is not None and (not isinstance(ign, np.ndarray) or ign.ndim != 2 or ign.shape[1] != 4
                                or not np.all(np.isfinite(ign))):
            raise ValueError(f"GroundTruth.ignore_boxes_xyxy must be a finite (K, 4) array or None, "
                             f"got {getattr(ign, 'shape', type(ign))}")

    def __len__(self) -> int:
        return int(self.boxes_xyxy.shape[0])
