"""Task-aligned assigner (TAL, Feng et al. 2021 "TOOD"), as YOLOv8 uses it.

For every ground-truth box it decides which anchor points learn that box:
1. candidates: anchor points whose centre lies inside the gt box;
2. alignment metric t = s^alpha * IoU^beta, where s is the predicted score of
   the gt's class at the anchor and IoU that of the predicted box with the gt
   (alpha 0.5, beta 6.0: localisation quality dominates);
3. the top-k (10) candidates by t become positives of that gt;
4. an anchor claimed by several gts keeps the one it overlaps most.
Classification targets are soft: the positive's class gets t normalised so
that the best anchor of each gt reaches that gt's best IoU.

Also holds the elementwise box IoU / CIoU used by the loss and NMS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch


def bbox_iou(box1: torch.Tensor, box2: torch.Tensor, ciou: bool = False, eps: float = 1e-7) -> torch.Tensor:
    """IoU (or Complete-IoU) of xyxy boxes, broadcasting over leading dims.

    CIoU = IoU - d^2 / c^2 - alpha * v, with d the distance of the centres, c
    the diagonal of the smallest enclosing box, v = 4/pi^2 (atan(w2/h2) -
    atan(w1/h1))^2 the aspect-ratio term and alpha = v / (1 - IoU + v)
    (Zheng et al. 2020). Returns a tensor of the broadcast shape without the
    last dimension.
    """
    b1x1, b1y1, b1x2, b1y2 = box1.unbind(-1)
    b2x1, b2y1, b2x2, b2y2 = box2.unbind(-1)
    w1, h1 = (b1x2 - b1x1).clamp(min=0), (b1y2 - b1y1).clamp(min=0)
    w2, h2 = (b2x2 - b2x1).clamp(min=0), (b2y2 - b2y1).clamp(min=0)
    inter = (torch.minimum(b1x2, b2x2) - torch.maximum(b1x1, b2x1)).clamp(min=0) * \
            (torch.minimum(b1y2, b2y2) - torch.maximum(b1y1, b2y1)).clamp(min=0)
    union = w1 * h1 + w2 * h2 - inter + eps
    iou = inter / union
    if not ciou:
        return iou
    cw = torch.maximum(b1x2, b2x2) - torch.minimum(b1x1, b2x1)
    ch = torch.maximum(b1y2, b2y2) - torch.minimum(b1y1, b2y1)
    c2 = cw ** 2 + ch ** 2 + eps
    rho2 = ((b2x1 + b2x2 - b1x1 - b1x2) ** 2 + (b2y1 + b2y2 - b1y1 - b1y2) ** 2) / 4.0
    v = (4.0 / math.pi ** 2) * (torch.atan(w2 / (h2 + eps)) - torch.atan(w1 / (h1 + eps))) ** 2
    with torch.no_grad():
        alpha = v / (v - iou + (1.0 + eps))
    return iou - (rho2 / c2 + v * alpha)


@dataclass(frozen=True)
class AssignerConfig:
    """TAL parameters: top_k candidates per gt, score exponent alpha, IoU exponent beta."""

    top_k: int = 10
    alpha: float = 0.5
    beta: float = 6.0
    eps: float = 1e-9

    def __post_init__(self) -> None:
        if not isinstance(self.top_k, int) or self.top_k < 1:
            raise ValueError(f"AssignerConfig.top_k must be a positive int, got {self.top_k!r}")
        if self.alpha < 0:
            raise ValueError(f"AssignerConfig.alpha must be >= 0, got {self.alpha}")
        if self.beta < 0:
            raise ValueError(f"AssignerConfig.beta must be >= 0, got {self.beta}")
        if self.eps <= 0:
            raise ValueError(f"AssignerConfig.eps must be > 0, got {self.eps}")


@dataclass
class Assignment:
    """Result of the assigner for a batch (A anchors, C classes).

    labels (B, A) int64 class of the assigned gt; boxes (B, A, 4) its xyxy box
    (same units as the gt boxes); scores (B, A, C) soft class targets;
    fg_mask (B, A) bool positives; gt_index (B, A) int64 index of the
    assigned gt within its image (0 where not positive).
    """

    labels: torch.Tensor
    boxes: torch.Tensor
    scores: torch.Tensor
    fg_mask: torch.Tensor
    gt_index: torch.Tensor


class TaskAlignedAssigner:
    """Callable assigner; see the module docstring for the rule."""

    def __init__(self, config: AssignerConfig = AssignerConfig()):
        self.config = config

    @torch.no_grad()
    def __call__(self, pred_scores: torch.Tensor, pred_boxes: torch.Tensor, anchor_points: torch.Tensor,
                 gt_labels: torch.Tensor, gt_boxes: torch.Tensor, gt_valid: torch.Tensor) -> Assignment:
        """Assign gts to anchors.

        pred_scores (B, A, C) probabilities; pred_boxes (B, A, 4) xyxy;
        anchor_points (A, 2) xy, same units as the boxes; gt_labels (B, M)
        int64; gt_boxes (B, M, 4) xyxy; gt_valid (B, M) bool (padding False).
        """
        cfg = self.config
        bsz, num_anchors, num_classes = pred_scores.shape
        m = gt_boxes.shape[1]
        device = pred_scores.device
        if m == 0 or not bool(gt_valid.any()):
            return Assignment(torch.zeros(bsz, num_anchors, dtype=torch.long, device=device),
                              torch.zeros(bsz, num_anchors, 4, device=device),
                              torch.zeros_like(pred_scores),
                              torch.zeros(bsz, num_anchors, dtype=torch.bool, device=device),
                              torch.zeros(bsz, num_anchors, dtype=torch.long, device=device))
        # 1. anchor centres strictly inside each gt box: (B, M, A)
        pts = anchor_points[None, None]                     # (1, 1, A, 2)
        lt = pts - gt_boxes[:, :, None, :2]
        rb = gt_boxes[:, :, None, 2:] - pts
        inside = torch.cat((lt, rb), dim=-1).amin(dim=-1) > cfg.eps
        candidates = inside & gt_valid[:, :, None]
        # 2. alignment metric
        iou = bbox_iou(gt_boxes[:, :, None, :], pred_boxes[:, None, :, :]).clamp(min=0)   # (B, M, A)
        labels = gt_labels.clamp(0, num_classes - 1)
        score = torch.gather(pred_scores.transpose(1, 2), 1,
                             labels[:, :, None].expand(-1, -1, num_anchors))             # (B, M, A)
        metric = score.pow(cfg.alpha) * iou.pow(cfg.beta)
        metric = torch.where(candidates, metric, torch.zeros_like(metric))
        iou = torch.where(candidates, iou, torch.zeros_like(iou))
        # 3. top-k candidates per gt (only real candidates count)
        k = min(cfg.top_k, num_anchors)
        # Break ties among zero-metric candidates in favour of candidates over non-candidates.
        ranking = metric + candidates.float() * 1e-12
        topk_idx = ranking.topk(k, dim=-1).indices                                       # (B, M, k)
        in_topk = torch.zeros_like(candidates).scatter_(-1, topk_idx, True)
        pos = in_topk & candidates                                                       # (B, M, A)
        # 4. anchors claimed by several gts keep the gt of highest IoU
        multi = pos.sum(dim=1) > 1                                                       # (B, A)
        if bool(multi.any()):
            best = torch.where(pos, iou, torch.full_like(iou, -1.0)).argmax(dim=1)       # (B, A)
            best_onehot = torch.zeros_like(pos).scatter_(1, best[:, None, :], True)
            pos = torch.where(multi[:, None, :], best_onehot & pos, pos)
        fg_mask = pos.any(dim=1)                                                         # (B, A)
        gt_index = pos.float().argmax(dim=1)                                             # (B, A)
        # targets
        t_labels = torch.gather(labels, 1, gt_index)
        t_boxes = torch.gather(gt_boxes, 1, gt_index[..., None].expand(-1, -1, 4))
        # normalised alignment: per gt, scale metric so its max equals the gt's max IoU
        # (iou^6 of a poor early prediction is ~1e-13, so no additive eps here)
        metric = metric * pos
        max_metric = metric.amax(dim=-1, keepdim=True)
        max_iou = (iou * pos).amax(dim=-1, keepdim=True)
        norm = (metric * max_iou / max_metric.clamp(min=1e-30)).amax(dim=1)                   # (B, A)
        t_scores = torch.zeros_like(pred_scores)
        t_scores.scatter_(-1, t_labels[..., None], 1.0)
        t_scores = t_scores * (norm * fg_mask)[..., None]
        return Assignment(t_labels, t_boxes, t_scores, fg_mask, torch.where(fg_mask, gt_index, 0))
