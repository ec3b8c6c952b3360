"""Training losses of the YOLOv8-style detector and segmenter.

total = box_gain * CIoU loss + cls_gain * BCE + dfl_gain * DFL
        (+ mask_gain * (mask BCE + mask_dice_weight * mask Dice))

* classification: binary cross-entropy of every anchor's class logits against
  the assigner's soft targets, summed and divided by the sum of the targets;
* box: (1 - CIoU) of positive anchors, weighted by their target score;
* DFL: cross-entropy of the two bins around the true side distance, weighted
  by their linear-interpolation weights (distribution focal loss);
* mask: per positive anchor, BCE of sigmoid(coefficients . prototypes)
  against the assigned gt mask at prototype resolution, only inside the gt
  box, averaged over the box area; with ``mask_dice_weight`` > 0 plus that
  weight times the soft Dice loss of the same mask inside the same box
  (1 - (2 sum(p t) + 1) / (sum(p) + sum(t) + 1)). Why: the area-averaged
  BCE of a thin structure (the 2-5 px stems of a defoliated plant fill a few
  per cent of its box) is already low when the stems are left out; Dice
  scores the overlap itself, as the mask IoU of the evaluation does.

Targets are a flat batch (the same layout the data loader's collate yields):
``batch_idx (N,)`` int64 image of each gt, ``classes (N,)`` int64,
``boxes_xyxy (N, 4)`` float [network-input px], and for segmentation
``masks (N, h, w)`` float 0..1 at any resolution proportional to the input
(resized to the prototype grid here). Optional don't-care regions:
``ignore_batch_idx (K,)`` and ``ignore_boxes_xyxy (K, 4)`` [network-input px]:
anchors whose centre lies in one (grown by half the anchor's stride, so that
boxes smaller than a cell still cover their cell) and that the assigner did
not make positive get no classification loss, i.e. are not pushed towards
background (objects the labelling rules leave out, e.g. far bolls).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Tuple

import torch
import torch.nn.functional as F

from .assigner import AssignerConfig, TaskAlignedAssigner, bbox_iou
from .heads import dfl_expectation, dist_to_xyxy, make_anchors, xyxy_to_dist


@dataclass(frozen=True)
class LossConfig:
    """Loss gains (YOLOv8 defaults) and the assigner's parameters."""

    box_gain: float = 7.5
    cls_gain: float = 0.5
    dfl_gain: float = 1.5
    mask_gain: float = 7.5
    mask_dice_weight: float = 0.0
    assigner: AssignerConfig = AssignerConfig()

    def __post_init__(self) -> None:
        for name in ("box_gain", "cls_gain", "dfl_gain", "mask_gain", "mask_dice_weight"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < float("inf"):
                raise ValueError(f"LossConfig.{name} must be a finite number >= 0, got {v!r}")


def soft_dice_loss(logits: torch.Tensor, target: torch.Tensor, inside: torch.Tensor) -> torch.Tensor:
    """Per-mask soft Dice loss (n,) of (n, h, w) logits against 0..1 targets, only where ``inside``.

    1 - (2 sum(p t) + 1) / (sum(p) + sum(t) + 1) with p = sigmoid(logits): 0
    for a perfect mask, near 1 when the prediction misses the target; the +1
    keeps an empty target with an empty prediction at 0.
    """
    region = inside.to(logits.dtype)
    p = logits.sigmoid() * region
    t = target * region
    overlap = (p * t).flatten(1).sum(-1)
    return 1.0 - (2.0 * overlap + 1.0) / (p.flatten(1).sum(-1) + t.flatten(1).sum(-1) + 1.0)


def pad_targets(batch_size: int, batch_index: torch.Tensor, classes: torch.Tensor,
                boxes: torch.Tensor) -> Tuple[torch.Tensor, torch.Tensor, torch.Tensor, List[torch.Tensor]]:
    """Flat targets -> padded (B, M, ...) labels, boxes, valid mask, and per-image index lists."""
    device = boxes.device
    per_image = [torch.nonzero(batch_index == b, as_tuple=False).flatten() for b in range(batch_size)]
    m = max([len(ix) for ix in per_image] + [0])
    labels = torch.zeros(batch_size, m, dtype=torch.long, device=device)
    pboxes = torch.zeros(batch_size, m, 4, dtype=boxes.dtype, device=device)
    valid = torch.zeros(batch_size, m, dtype=torch.bool, device=device)
    for b, ix in enumerate(per_image):
        n = len(ix)
        if n:
            labels[b, :n] = classes[ix]
            pboxes[b, :n] = boxes[ix]
            valid[b, :n] = True
    return labels, pboxes, valid, per_image


def dfl_loss(pred_distri: torch.Tensor, target_dist: torch.Tensor, reg_max: int) -> torch.Tensor:
    """Distribution focal loss of (n, 4 * reg_max) logits for (n, 4) target distances -> (n,)."""
    logits = pred_distri.reshape(-1, reg_max)
    t = target_dist.reshape(-1)
    left = t.long().clamp(max=reg_max - 2)
    right = left + 1
    w_left = right.float() - t
    w_right = 1.0 - w_left
    loss = F.cross_entropy(logits, left, reduction="none") * w_left + \
        F.cross_entropy(logits, right, reduction="none") * w_right
    return loss.reshape(-1, 4).mean(dim=-1)


def anchors_in_ignore_boxes(centres_px: torch.Tensor, strides_px: torch.Tensor, batch_size: int,
                            batch_index: torch.Tensor, boxes_xyxy: torch.Tensor) -> torch.Tensor:
    """(B, A) bool: anchor centre (A, 2) [px] inside one of its image's ignore boxes.

    Each box is grown by half the anchor's stride (strides_px (A, 1) [px]) on
    every side, so a box smaller than a grid cell still covers the cell it
    lies in.
    """
    if boxes_xyxy.ndim != 2 or boxes_xyxy.shape[1] != 4 or batch_index.shape != (boxes_xyxy.shape[0],):
        raise ValueError("ignore targets: ignore_batch_idx (K,) and ignore_boxes_xyxy (K, 4) must agree in K")
    half = 0.5 * strides_px.reshape(-1)                                    # (A,)
    x, y = centres_px[:, 0], centres_px[:, 1]
    b = boxes_xyxy[:, :, None]                                             # (K, 4, 1)
    inside = ((x >= b[:, 0] - half) & (x <= b[:, 2] + half) &
              (y >= b[:, 1] - half) & (y <= b[:, 3] + half))               # (K, A)
    out = torch.zeros(batch_size, centres_px.shape[0], dtype=torch.bool, device=centres_px.device)
    for i in range(batch_size):
        sel = batch_index == i
        if bool(sel.any()):
            out[i] = inside[sel].any(dim=0)
    return out


def _check_targets(targets: Dict[str, torch.Tensor], need_masks: bool) -> None:
    for key in ("batch_idx", "classes", "boxes_xyxy") + (("masks",) if need_masks else ()):
        if key not in targets:
            raise ValueError(f"targets are missing '{key}'")
    n = targets["classes"].shape[0]
    if targets["boxes_xyxy"].shape != (n, 4) or targets["batch_idx"].shape != (n,):
        raise ValueError("targets: batch_idx (N,), classes (N,) and boxes_xyxy (N, 4) must agree in N")
    if need_masks and targets["masks"].shape[0] != n:
        raise ValueError("targets: masks must have one mask per box")


class YoloLoss:
    """Loss of either network; call with the model's train-mode output.

    ``loss(outputs, targets, image_size_hw)`` returns (total, parts) with
    parts = {'box', 'cls', 'dfl'[, 'mask']} detached floats per image batch.
    """

    def __init__(self, num_classes: int, reg_max: int = 16, strides=(8, 16, 32),
                 config: LossConfig = LossConfig()):
        self.num_classes = int(num_classes)
        self.reg_max = int(reg_max)
        self.strides = tuple(strides)
        self.config = config
        self.assigner = TaskAlignedAssigner(config.assigner)

    def __call__(self, outputs, targets: Dict[str, torch.Tensor]):
        segment = isinstance(outputs, tuple)
        maps, coeffs, protos = outputs if segment else (outputs, None, None)
        _check_targets(targets, segment)
        bsz = maps[0].shape[0]
        no = 4 * self.reg_max + self.num_classes
        flat = torch.cat([m.reshape(bsz, no, -1) for m in maps], dim=2).transpose(1, 2)
        pred_distri, pred_logits = flat[..., :4 * self.reg_max], flat[..., 4 * self.reg_max:]
        points, strides = make_anchors(maps, self.strides)           # grid units, px per cell
        pred_boxes = dist_to_xyxy(dfl_expectation(pred_distri, self.reg_max), points)   # grid units

        labels, gt_boxes, valid, per_image = pad_targets(bsz, targets["batch_idx"].long(),
                                                         targets["classes"].long(),
                                                         targets["boxes_xyxy"].to(flat.dtype))
        asg = self.assigner(pred_logits.detach().sigmoid(), (pred_boxes.detach() * strides).to(gt_boxes.dtype),
                            points * strides, labels, gt_boxes, valid)
        score_sum = asg.scores.sum().clamp(min=1.0)
        fg = asg.fg_mask
        bce = F.binary_cross_entropy_with_logits(pred_logits, asg.scores, reduction="none")
        ignore_boxes = targets.get("ignore_boxes_xyxy")
        if ignore_boxes is not None and ignore_boxes.shape[0]:
            dont_care = anchors_in_ignore_boxes(points * strides, strides, bsz,
                                                targets["ignore_batch_idx"].long(), ignore_boxes.to(flat.dtype))
            bce = bce * (~(dont_care & ~fg)).to(bce.dtype)[..., None]
        loss_cls = bce.sum() / score_sum

        zero = flat.sum() * 0.0
        loss_box, loss_dfl, loss_mask = zero, zero, zero
        if bool(fg.any()):
            weight = asg.scores.sum(-1)[fg]
            t_boxes = asg.boxes / strides[None]                        # grid units
            iou = bbox_iou(pred_boxes[fg], t_boxes[fg], ciou=True)
            loss_box = ((1.0 - iou) * weight).sum() / score_sum
            pts = points[None].expand(bsz, -1, -1)[fg]
            t_dist = xyxy_to_dist(t_boxes[fg], pts, self.reg_max - 1 - 0.01)
            loss_dfl = (dfl_loss(pred_distri[fg], t_dist, self.reg_max) * weight).sum() / score_sum
            if segment:
                loss_mask = self._mask_loss(coeffs, protos, targets["masks"], per_image, asg, maps)
        c = self.config
        total = c.box_gain * loss_box + c.cls_gain * loss_cls + c.dfl_gain * loss_dfl
        parts = {"box": float(loss_box.detach()), "cls": float(loss_cls.detach()), "dfl": float(loss_dfl.detach())}
        if segment:
            total = total + c.mask_gain * loss_mask
            parts["mask"] = float(loss_mask.detach())
        return total, parts

    def _mask_loss(self, coeffs, protos, masks, per_image, asg, maps) -> torch.Tensor:
        bsz, k, hp, wp = protos.shape
        input_h, input_w = maps[0].shape[-2] * self.strides[0], maps[0].shape[-1] * self.strides[0]
        masks = masks.to(protos.dtype)
        if masks.shape[-2:] != (hp, wp):
            masks = F.interpolate(masks[:, None], size=(hp, wp), mode="bilinear", align_corners=False)[:, 0]
        scale = torch.tensor([wp / input_w, hp / input_h, wp / input_w, hp / input_h],
                             dtype=protos.dtype, device=protos.device)
        ys = torch.arange(hp, dtype=protos.dtype, device=protos.device)[:, None] + 0.5
        xs = torch.arange(wp, dtype=protos.dtype, device=protos.device)[None, :] + 0.5
        total, count = protos.sum() * 0.0, 0
        for b in range(bsz):
            fg = asg.fg_mask[b]
            n = int(fg.sum())
            if n == 0:
                continue
            gt_ix = per_image[b][asg.gt_index[b][fg]]                      # flat target indices
            target = masks[gt_ix]                                          # (n, hp, wp)
            logits = (coeffs[b][:, fg].T @ protos[b].reshape(k, -1)).reshape(n, hp, wp)
            box = asg.boxes[b][fg] * scale                                 # proto px
            inside = (xs >= box[:, 0, None, None]) & (xs < box[:, 2, None, None]) & \
                     (ys >= box[:, 1, None, None]) & (ys < box[:, 3, None, None])
            area = inside.flatten(1).sum(-1).clamp(min=1)
            bce = F.binary_cross_entropy_with_logits(logits, target, reduction="none")
            total = total + ((bce * inside).flatten(1).sum(-1) / area).sum()
            if self.config.mask_dice_weight > 0:
                total = total + self.config.mask_dice_weight * soft_dice_loss(logits, target, inside).sum()
            count += n
        return total / max(count, 1)
