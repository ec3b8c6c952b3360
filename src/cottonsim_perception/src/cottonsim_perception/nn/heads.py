"""Anchor-free decoupled heads of YOLOv8: DFL box regression, classes, mask prototypes.

Every cell of the stride 8/16/32 grids is an 'anchor point' (its centre). For
each one the head predicts
* box: for each side (left, top, right, bottom) a discrete distribution over
  ``reg_max`` bins of the distance from the anchor point to that side, in
  grid cells; the distance is the distribution's expected value (DFL,
  Li et al. 2020, "Generalized Focal Loss"), so a distance of up to
  reg_max - 1 cells (15 cells = 480 px at stride 32) can be represented;
* class logits (sigmoid per class, no objectness);
* for segmentation, ``num_prototypes`` mask coefficients; a separate 'Proto'
  branch turns the stride-8 features into ``num_prototypes`` prototype masks at
  stride 4 (or 2, or 1 with a full-resolution detail path from the input
  image, see :class:`Proto`), and an instance mask is sigmoid(coefficients . prototypes).
Box and class branches are separate ('decoupled'), each two 3x3 Convs + a 1x1.
"""
from __future__ import annotations

import math
from typing import List, Optional, Sequence, Tuple

import torch
import torch.nn as nn
import torch.nn.functional as F

from .blocks import Conv

STRIDES = (8, 16, 32)


def make_anchors(feats: Sequence[torch.Tensor], strides: Sequence[int] = STRIDES,
                 offset: float = 0.5) -> Tuple[torch.Tensor, torch.Tensor]:
    """Anchor points of all levels, level by level, row-major.

    Returns points (A, 2) as (x, y) in grid units of their level (cell centres,
    i.e. +0.5) and strides (A, 1) [px per cell]; a point in input pixels is
    points * strides.
    """
    points, stride_list = [], []
    for f, s in zip(feats, strides):
        h, w = f.shape[-2:]
        sy = torch.arange(h, dtype=f.dtype, device=f.device) + offset
        sx = torch.arange(w, dtype=f.dtype, device=f.device) + offset
        yy, xx = torch.meshgrid(sy, sx, indexing="ij")
        points.append(torch.stack((xx, yy), dim=-1).reshape(-1, 2))
        stride_list.append(torch.full((h * w, 1), float(s), dtype=f.dtype, device=f.device))
    return torch.cat(points), torch.cat(stride_list)


def dfl_expectation(distri: torch.Tensor, reg_max: int) -> torch.Tensor:
    """Expected distances from DFL logits: (..., 4 * reg_max) -> (..., 4) [grid cells]."""
    shape = distri.shape[:-1]
    prob = distri.reshape(*shape, 4, reg_max).softmax(dim=-1)
    bins = torch.arange(reg_max, dtype=prob.dtype, device=prob.device)
    return (prob * bins).sum(dim=-1)


def dist_to_xyxy(dist_ltrb: torch.Tensor, points: torch.Tensor) -> torch.Tensor:
    """Side distances (l, t, r, b) around anchor points -> boxes (x1, y1, x2, y2), same units."""
    lt, rb = dist_ltrb[..., :2], dist_ltrb[..., 2:]
    return torch.cat((points - lt, points + rb), dim=-1)


def xyxy_to_dist(boxes: torch.Tensor, points: torch.Tensor, max_dist: float) -> torch.Tensor:
    """Boxes -> side distances (l, t, r, b) from anchor points, clipped to [0, max_dist]."""
    lt = points - boxes[..., :2]
    rb = boxes[..., 2:] - points
    return torch.cat((lt, rb), dim=-1).clamp(0, max_dist)


class DetectHead(nn.Module):
    """Decoupled anchor-free detection head over three levels.

    forward(feats) returns, per level, a map (B, 4 * reg_max + num_classes, H, W):
    box distribution logits first, class logits after.
    """

    def __init__(self, num_classes: int, in_channels: Sequence[int], reg_max: int = 16,
                 strides: Sequence[int] = STRIDES):
        super().__init__()
        self.num_classes = int(num_classes)
        self.reg_max = int(reg_max)
        self.strides = tuple(int(s) for s in strides)
        self.outputs_per_anchor = 4 * self.reg_max + self.num_classes
        c_box = max(16, in_channels[0] // 4, 4 * self.reg_max)
        c_cls = max(in_channels[0], min(self.num_classes, 100))
        self.box = nn.ModuleList(nn.Sequential(Conv(c, c_box, 3), Conv(c_box, c_box, 3),
                                               nn.Conv2d(c_box, 4 * self.reg_max, 1)) for c in in_channels)
        self.cls = nn.ModuleList(nn.Sequential(Conv(c, c_cls, 3), Conv(c_cls, c_cls, 3),
                                               nn.Conv2d(c_cls, self.num_classes, 1)) for c in in_channels)
        self.reset_bias()

    def reset_bias(self, image_size_px: int = 640) -> None:
        """YOLOv8's prior: box logits 1.0, class prior ~5 objects per image of 640 px."""
        for box, cls, s in zip(self.box, self.cls, self.strides):
            nn.init.constant_(box[-1].bias, 1.0)
            prior = 5.0 / self.num_classes / (image_size_px / s) ** 2
            nn.init.constant_(cls[-1].bias, math.log(prior / (1.0 - prior)))

    def forward(self, feats: List[torch.Tensor]) -> List[torch.Tensor]:
        return [torch.cat((b(f), c(f)), dim=1) for f, b, c in zip(feats, self.box, self.cls)]

    def flatten(self, maps: List[torch.Tensor]) -> Tuple[torch.Tensor, torch.Tensor]:
        """Level maps -> (box logits (B, A, 4 * reg_max), class logits (B, A, nc))."""
        b = maps[0].shape[0]
        flat = torch.cat([m.reshape(b, self.outputs_per_anchor, -1) for m in maps], dim=2).transpose(1, 2)
        return flat[..., :4 * self.reg_max], flat[..., 4 * self.reg_max:]

    def decode(self, maps: List[torch.Tensor]) -> torch.Tensor:
        """Level maps -> (B, A, 4 + nc): boxes xyxy [input px] and class probabilities."""
        distri, logits = self.flatten(maps)
        points, strides = make_anchors(maps, self.strides)
        boxes = dist_to_xyxy(dfl_expectation(distri, self.reg_max), points) * strides
        return torch.cat((boxes, logits.sigmoid()), dim=-1)


PROTO_STRIDES = (4, 2, 1)


class Proto(nn.Module):
    """Prototype-mask branch: stride-8 features -> k prototypes at stride 4, 2 or 1.

    stride 4 (YOLOv8): 3x3 conv, x2 transposed conv, 3x3 conv, 1x1 conv to k.
    stride 2 adds one more x2 stage before the 1x1: a 2x2 stride-2 transposed
    conv (hidden -> hidden channels, no activation: the 1x1 conv's SiLU
    follows), so each stride-4 pixel gets four learned sub-pixels. It starts
    as a nearest-neighbour copy (identity per channel, zero bias), so a
    stride-2 network initialised from stride-4 weights first reproduces the
    stride-4 masks exactly, upsampled; fine-tuning then learns the detail.
    Masks at 1/2 of the network input; no 3x3 conv at 4x the pixels (it
    cost ~30 % more per frame).

    stride 1 (thin stems of defoliated plants, 1-2 input px wide, are below
    the stride-2 grid): the stride-2 prototypes, repeated 2 x 2 (nearest
    neighbour) to the full input, plus a cheap detail path computed from the
    letterboxed input image itself: a 3x3 conv 3 -> ``detail_channels`` with
    BN + SiLU at full resolution, then a 1x1 conv (with bias) to k. The
    coarse prototypes say 'near a plant', the detail says 'stem-coloured
    pixel here'; nothing at hidden width runs at full resolution. The detail
    is added after the prototypes' SiLU, i.e. linearly, so that an instance's
    mask logit c . protos = up(c . coarse) + (W^T c) . detail + c . bias
    can be evaluated per instance after NMS (see :meth:`parts` and
    ``postprocess``) instead of on k full-resolution prototype maps, which
    cost ~60 % more per frame when the network output them. The 1x1 conv starts at zero, so a
    stride-1 network initialised from stride-2 weights first reproduces the
    stride-2 prototypes exactly, each pixel repeated 2 x 2.
    forward(x, image) needs the network input image for stride 1.
    """

    def __init__(self, c_in: int, hidden: int = 64, num_prototypes: int = 32, stride: int = 4,
                 detail_channels: int = 8):
        super().__init__()
        if stride not in PROTO_STRIDES:
            raise ValueError(f"Proto stride must be one of {PROTO_STRIDES}, got {stride!r}")
        if not isinstance(detail_channels, int) or detail_channels < 1:
            raise ValueError(f"Proto detail_channels must be a positive int, got {detail_channels!r}")
        self.stride = int(stride)
        self.cv1 = Conv(c_in, hidden, 3)
        self.upsample = nn.ConvTranspose2d(hidden, hidden, 2, 2, 0, bias=True)
        self.cv2 = Conv(hidden, hidden, 3)
        if self.stride <= 2:
            self.upsample2 = nn.ConvTranspose2d(hidden, hidden, 2, 2, 0, bias=True)
            with torch.no_grad():
                self.upsample2.weight.zero_()
                self.upsample2.bias.zero_()
                idx = torch.arange(hidden)
                self.upsample2.weight[idx, idx] = 1.0          # (in, out, 2, 2): copy to all 4 sub-pixels
        self.cv3 = Conv(hidden, num_prototypes, 1)
        if self.stride == 1:
            self.detail = Conv(3, detail_channels, 3)                          # full input resolution
            self.detail_out = nn.Conv2d(detail_channels, num_prototypes, 1, bias=True)
            nn.init.zeros_(self.detail_out.weight)                             # start: no detail
            nn.init.zeros_(self.detail_out.bias)

    def forward(self, x: torch.Tensor, image: Optional[torch.Tensor] = None) -> torch.Tensor:
        y = self.cv2(self.upsample(self.cv1(x)))
        if self.stride <= 2:
            y = self.upsample2(y)
        if self.stride != 1:
            return self.cv3(y)
        coarse, detail = self._coarse_detail(y, image)
        return F.interpolate(coarse, scale_factor=2.0, mode="nearest") + self.detail_out(detail)

    def _coarse_detail(self, y: torch.Tensor, image: Optional[torch.Tensor]):
        if image is None:
            raise ValueError("Proto(stride=1) needs the network input image for its detail path")
        return self.cv3(y), self.detail(image)

    def parts(self, x: torch.Tensor, image: torch.Tensor):
        """Stride 1 only, for inference: (coarse prototypes (B, k, H/2, W/2),
        detail features (B, detail_channels, H, W)); forward() is
        up(coarse) + detail_out(detail)."""
        if self.stride != 1:
            raise ValueError(f"Proto.parts is for stride 1 only, this branch has stride {self.stride}")
        return self._coarse_detail(self.upsample2(self.cv2(self.upsample(self.cv1(x)))), image)

    def detail_coefficients(self, coeffs: torch.Tensor) -> torch.Tensor:
        """Stride 1: per-anchor detail coefficients of mask coefficients (B, k, A)
        -> (B, detail_channels + 1, A): W^T c and the bias term b . c, so that
        c . forward() = up(c . coarse) + (W^T c) . detail + b . c."""
        w = self.detail_out.weight[:, :, 0, 0]                                 # (k, d)
        return torch.cat((torch.einsum("kd,bka->bda", w, coeffs),
                          torch.einsum("k,bka->ba", self.detail_out.bias, coeffs)[:, None]), dim=1)


class SegmentHead(nn.Module):
    """Detection head plus per-anchor mask coefficients and the Proto branch.

    forward(feats) -> (level maps as DetectHead, coefficients (B, k, A),
    prototypes (B, k, H/s, W/s), s = proto_stride, 4, 2 or 1); stride 1 needs
    forward(feats, image) with the network input image (its detail path).
    """

    def __init__(self, num_classes: int, in_channels: Sequence[int], num_prototypes: int = 32,
                 proto_channels: int = 64, reg_max: int = 16, strides: Sequence[int] = STRIDES,
                 proto_stride: int = 4, detail_channels: int = 8):
        super().__init__()
        self.detect = DetectHead(num_classes, in_channels, reg_max, strides)
        self.num_prototypes = int(num_prototypes)
        self.proto = Proto(in_channels[0], proto_channels, self.num_prototypes, proto_stride, detail_channels)
        c_mask = max(in_channels[0] // 4, self.num_prototypes)
        self.coef = nn.ModuleList(nn.Sequential(Conv(c, c_mask, 3), Conv(c_mask, c_mask, 3),
                                                nn.Conv2d(c_mask, self.num_prototypes, 1)) for c in in_channels)

    def coefficients(self, feats: List[torch.Tensor]) -> torch.Tensor:
        """Mask coefficients of every anchor, level by level: (B, k, A)."""
        b = feats[0].shape[0]
        return torch.cat([m(f).reshape(b, self.num_prototypes, -1) for f, m in zip(feats, self.coef)], dim=2)

    def forward(self, feats: List[torch.Tensor], image: Optional[torch.Tensor] = None):
        return self.detect(feats), self.coefficients(feats), self.proto(feats[0], image)

    def forward_detail(self, feats: List[torch.Tensor], image: torch.Tensor):
        """proto_stride 1, inference: (level maps, coefficients (B, k, A), coarse
        prototypes, detail features), see Proto.parts; no full-resolution prototypes."""
        return (self.detect(feats), self.coefficients(feats)) + tuple(self.proto.parts(feats[0], image))
