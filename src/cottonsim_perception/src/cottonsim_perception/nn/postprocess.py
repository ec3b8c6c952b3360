"""Decoded network output -> per-image :class:`~cottonsim_perception.types.Detections`.

Steps per image: keep anchors whose best class probability reaches the
confidence threshold (one label per anchor: its best class); keep at most
``max_candidates`` of them by score; per-class non-maximum suppression (boxes of
different classes never suppress each other); at most ``max_detections``;
for segmentation, masks = sigmoid(coefficients . prototypes) zeroed outside
the box (for a proto_stride-1 segmenter, whose eval output is coarse
prototypes + full-resolution detail features, the logit is assembled per
kept instance, see :func:`instance_mask_logits`; both only inside the box,
:func:`box_soft_masks`), then boxes and masks are mapped back through the letterbox to the
original image.

torchvision is not available, so NMS is written here: greedy, on a
precomputed IoU matrix.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional, Sequence

import numpy as np
import torch

from cottonsim_common.validation import require_fields

from ..types import Detections
from .assigner import bbox_iou
from .letterbox import LetterboxTransform, MaskWindow, dense_masks


@dataclass(frozen=True)
class PostprocessConfig:
    """conf_threshold: min class probability kept; iou_threshold: NMS overlap
    above which the lower-scored box is dropped; max_candidates: boxes entering
    NMS; max_detections: boxes kept per image; mask_threshold: probability of a
    mask pixel being inside."""

    conf_threshold: float = 0.25
    iou_threshold: float = 0.7
    max_candidates: int = 3000
    max_detections: int = 300
    mask_threshold: float = 0.5

    def __post_init__(self) -> None:
        require_fields(self, "PostprocessConfig.", fractions=("conf_threshold", "iou_threshold", "mask_threshold"),
                       counts=("max_candidates", "max_detections"))


def pairwise_iou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """IoU matrix (N, M) of xyxy boxes a (N, 4) and b (M, 4)."""
    return bbox_iou(a[:, None, :], b[None, :, :])


def nms(boxes: torch.Tensor, scores: torch.Tensor, iou_threshold: float) -> torch.Tensor:
    """Greedy NMS: indices of kept boxes, by descending score.

    A box is dropped when its IoU with an already kept, higher-scored box
    exceeds ``iou_threshold``.
    """
    if boxes.shape[0] == 0:
        return torch.zeros(0, dtype=torch.long)
    order = torch.argsort(scores, descending=True, stable=True)
    over = (pairwise_iou(boxes[order], boxes[order]) > iou_threshold).cpu().numpy()
    n = over.shape[0]
    suppressed = np.zeros(n, dtype=bool)
    keep = []
    for i in range(n):
        if suppressed[i]:
            continue
        keep.append(i)
        suppressed |= over[i]
    return order[torch.as_tensor(keep, dtype=torch.long, device=order.device)]


def batched_nms(boxes: torch.Tensor, scores: torch.Tensor, classes: torch.Tensor,
                iou_threshold: float) -> torch.Tensor:
    """Per-class NMS by shifting each class's boxes to a disjoint region."""
    if boxes.shape[0] == 0:
        return torch.zeros(0, dtype=torch.long)
    offset = classes.to(boxes.dtype)[:, None] * (boxes.max() + 1.0)
    return nms(boxes + offset, scores, iou_threshold)


def box_windows(boxes: torch.Tensor, height: int, width: int) -> List[Optional[tuple]]:
    """Per box (xyxy in mask pixels) the pixels whose centre lies in it, as one
    row range times one column range: (r0, r1, c0, c1), or None when it holds
    no pixel centre."""
    xs = torch.arange(width, dtype=boxes.dtype, device=boxes.device)[None, :] + 0.5
    ys = torch.arange(height, dtype=boxes.dtype, device=boxes.device)[None, :] + 0.5
    cols = ((xs >= boxes[:, 0:1]) & (xs < boxes[:, 2:3])).tolist()          # (n, w), one run of True
    rows = ((ys >= boxes[:, 1:2]) & (ys < boxes[:, 3:4])).tolist()
    windows: List[Optional[tuple]] = []
    for col, row in zip(cols, rows):
        if True not in col or True not in row:
            windows.append(None)
            continue
        windows.append((row.index(True), height - row[::-1].index(True),
                        col.index(True), width - col[::-1].index(True)))
    return windows


def crop_masks(masks: torch.Tensor, boxes: torch.Tensor) -> torch.Tensor:
    """Zero (n, h, w) masks outside their boxes (xyxy in mask pixels); returns a new tensor.

    A pixel is kept when its centre lies in the box. The kept pixels of a box
    are one row range times one column range (:func:`box_windows`), so the
    outside is zeroed by slices: the same values as multiplying by a
    full-size box mask, which cost ~2 ms per frame for 320x256 masks
    (proto_stride 1).
    """
    out = masks.clone()
    for i, win in enumerate(box_windows(boxes, masks.shape[1], masks.shape[2])):
        if win is None:
            out[i] = 0.0
            continue
        r0, r1, c0, c1 = win
        out[i, :r0] = 0.0
        out[i, r1:] = 0.0
        out[i, :, :c0] = 0.0
        out[i, :, c1:] = 0.0
    return out


def instance_mask_logits(extra: torch.Tensor, protos: torch.Tensor,
                         detail: Optional[torch.Tensor] = None) -> torch.Tensor:
    """Mask logits (n, h, w) of n kept instances of one image.

    extra: (n, >= k) the predictions' columns after the class probabilities;
    protos: (k, hp, wp). Without ``detail``: coefficients (first k columns)
    . prototypes, at the prototype grid. With detail features (d, H, W) of a
    proto_stride-1 segmenter (H, W = 2 hp, 2 wp): columns k .. k + d are the
    detail coefficients and column k + d the bias term, and the logit is
    up(c . protos) (nearest) + detail coefficients . detail + bias term, at
    H x W: the same as c . the train-mode full-resolution prototypes, for n
    masks instead of k prototype maps (see heads.Proto).
    """
    k, hp, wp = protos.shape
    logits = (extra[:, :k] @ protos.reshape(k, -1)).reshape(-1, hp, wp)
    if detail is None:
        return logits
    d, h, w = detail.shape
    if (h, w) != (2 * hp, 2 * wp) or extra.shape[1] < k + d + 1:
        raise ValueError(f"detail features {tuple(detail.shape)} do not fit prototypes {tuple(protos.shape)} "
                         f"and {extra.shape[1]} coefficient columns (need k + d + 1 = {k + d + 1})")
    fine = (extra[:, k:k + d] @ detail.reshape(d, -1)).reshape(-1, h, w) + extra[:, k + d, None, None]
    # + nearest x2 upsampling of the coarse logits, as a broadcast add (no upsampled copy)
    fine.view(-1, hp, 2, wp, 2).add_(logits[:, :, None, :, None])
    return fine


def box_soft_mask_windows(extra: torch.Tensor, protos: torch.Tensor, boxes: torch.Tensor,
                          detail: Optional[torch.Tensor] = None) -> List[Optional[MaskWindow]]:
    """Soft masks of n kept instances, each only inside its box's window.

    Per instance ``((r0, r1, c0, c1), soft)``: the window of mask pixels whose
    centres lie in the box (xyxy in mask pixels, :func:`box_windows`) and the
    sigmoid of the instance's mask logits there, (r1 - r0, c1 - c0); None for
    a box that holds no pixel centre. The mask is 0 outside the window. For a
    proto_stride-1 segmenter at 320x256 the logits are most of the
    per-instance work and a plant's box is a fraction of the frame, so only
    the window is computed.
    """
    k, hp, wp = protos.shape
    if detail is None:
        h, w = hp, wp
    else:
        d, h, w = detail.shape
        if (h, w) != (2 * hp, 2 * wp) or extra.shape[1] < k + d + 1:
            raise ValueError(f"detail features {tuple(detail.shape)} do not fit prototypes {tuple(protos.shape)} "
                             f"and {extra.shape[1]} coefficient columns (need k + d + 1 = {k + d + 1})")
    out: List[Optional[MaskWindow]] = []
    for i, win in enumerate(box_windows(boxes, h, w)):
        if win is None:
            out.append(None)
            continue
        r0, r1, c0, c1 = win
        if detail is None:
            logit = (extra[i, :k] @ protos[:, r0:r1, c0:c1].reshape(k, -1)).reshape(r1 - r0, c1 - c0)
        else:
            window = detail[:, r0:r1, c0:c1]
            logit = (extra[i, k:k + d] @ window.reshape(d, -1)).reshape(r1 - r0, c1 - c0) + extra[i, k + d]
            # the coarse logits of the prototype cells under the window, each repeated 2 x 2 (nearest)
            q0, q1, p0, p1 = r0 // 2, (r1 + 1) // 2, c0 // 2, (c1 + 1) // 2
            coarse = (extra[i, :k] @ protos[:, q0:q1, p0:p1].reshape(k, -1)).reshape(q1 - q0, p1 - p0)
            up = coarse.repeat_interleave(2, dim=0).repeat_interleave(2, dim=1)
            logit = logit + up[r0 - 2 * q0:r0 - 2 * q0 + (r1 - r0), c0 - 2 * p0:c0 - 2 * p0 + (c1 - c0)]
        out.append((win, logit.sigmoid()))
    return out


def box_soft_masks(extra: torch.Tensor, protos: torch.Tensor, boxes: torch.Tensor,
                   detail: Optional[torch.Tensor] = None) -> torch.Tensor:
    """Soft masks (n, h, w) of n kept instances: sigmoid of their mask logits
    inside their boxes (xyxy in mask pixels), 0 outside.

    The same values as ``crop_masks(instance_mask_logits(extra, protos,
    detail).sigmoid(), boxes)`` up to float rounding; the dense form of
    :func:`box_soft_mask_windows`.
    """
    h, w = protos.shape[1:] if detail is None else detail.shape[1:]
    windows = box_soft_mask_windows(extra, protos, boxes, detail)
    return dense_masks(windows, h, w, protos.dtype)


def postprocess(predictions: torch.Tensor, num_classes: int, transforms: Sequence[LetterboxTransform],
                protos: Optional[torch.Tensor] = None,
                config: PostprocessConfig = PostprocessConfig(),
                detail: Optional[torch.Tensor] = None) -> List[Detections]:
    """Turn eval-mode network output into one Detections per image.

    predictions: (B, A, 4 + nc [+ k [+ d + 1]]) from the model (boxes xyxy in
    input px); protos: (B, k, h, w) for segmentation, else None; transforms:
    the letterbox of each image; detail: (B, d, 2h, 2w) detail features of a
    proto_stride-1 segmenter (its third eval output), else None.
    """
    if predictions.ndim != 3 or predictions.shape[-1] < 4 + num_classes:
        raise ValueError(f"predictions must be (B, A, 4 + {num_classes} [+ k]), got {tuple(predictions.shape)}")
    if len(transforms) != predictions.shape[0]:
        raise ValueError(f"need one letterbox transform per image: {len(transforms)} for {predictions.shape[0]}")
    results = []
    for b, tf in enumerate(transforms):
        p = predictions[b]
        cls_prob = p[:, 4:4 + num_classes]
        score, label = cls_prob.max(dim=1)
        sel = score >= config.conf_threshold
        p, score, label = p[sel], score[sel], label[sel]
        if score.shape[0] > config.max_candidates:
            top = score.topk(config.max_candidates).indices
            p, score, label = p[top], score[top], label[top]
        keep = batched_nms(p[:, :4], score, label, config.iou_threshold)[:config.max_detections]
        p, score, label = p[keep], score[keep], label[keep]
        boxes_in = p[:, :4]
        masks = None
        if protos is not None:
            d_b = None if detail is None else detail[b]
            hm, wm = protos.shape[-2:] if d_b is None else d_b.shape[-2:]          # mask grid [px]
            scale = torch.tensor([wm / tf.dst_width, hm / tf.dst_height] * 2, dtype=protos.dtype)
            windows = box_soft_mask_windows(p[:, 4 + num_classes:], protos[b], boxes_in * scale, d_b)
            masks = tf.window_masks_to_original(windows, hm, wm, config.mask_threshold)
        boxes = tf.boxes_to_original(boxes_in.cpu().numpy()).astype(np.float32)
        results.append(Detections(boxes, score.cpu().numpy().astype(np.float32),
                                  label.cpu().numpy().astype(np.int64), masks))
    return results
