"""Building blocks of a YOLOv8-style network: Conv, Bottleneck, C2f, SPPF, backbone, neck.

The layout follows YOLOv8 (CSP-Darknet backbone with C2f stages, an SPPF at the
end, a PAN neck that fuses strides 8/16/32 top-down then bottom-up). Sizes are
scaled like YOLOv8's 'n/s/m' variants: ``width_multiple`` scales every channel
count (rounded up to a multiple of 8) and ``depth_multiple`` the number of
bottlenecks per C2f. YOLOv8n is width 0.25, depth 0.33; smaller values give the
CPU-sized variants this project uses.
"""
from __future__ import annotations

import math
from typing import List, Sequence, Tuple

import torch
import torch.nn as nn

# Base channel counts of YOLOv8 (P1..P5) and base repeats of the four backbone C2f stages.
BASE_WIDTHS = (64, 128, 256, 512, 1024)
BASE_DEPTHS = (3, 6, 6, 3)


def scale_width(channels: int, width_multiple: float, max_channels: int = 1024, divisor: int = 8) -> int:
    """Channel count after the width multiplier, a multiple of ``divisor`` (>= divisor)."""
    c = min(channels, max_channels) * width_multiple
    return max(divisor, int(math.ceil(c / divisor) * divisor))


def scale_depth(repeats: int, depth_multiple: float) -> int:
    """Number of repeats after the depth multiplier (at least 1)."""
    return max(1, int(round(repeats * depth_multiple))) if repeats > 1 else repeats


class Conv(nn.Module):
    """Conv2d (no bias) + BatchNorm + SiLU; 'same' padding for odd kernels."""

    def __init__(self, c_in: int, c_out: int, k: int = 1, s: int = 1, groups: int = 1, act: bool = True):
        super().__init__()
        self.conv = nn.Conv2d(c_in, c_out, k, s, k // 2, groups=groups, bias=False)
        # momentum 0.1 (YOLOv8: 0.03): short CPU runs of a few hundred steps need the
        # running statistics to follow the changing weights, else eval mode lags badly.
        self.bn = nn.BatchNorm2d(c_out, eps=1e-3, momentum=0.1)
        self.act = nn.SiLU(inplace=True) if act else nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.act(self.bn(self.conv(x)))

    @torch.no_grad()
    def fuse(self) -> None:
        """Fold the BatchNorm into the conv (inference only: ~1/3 fewer ops)."""
        if isinstance(self.bn, nn.Identity):
            return
        bn, conv = self.bn, self.conv
        factor = bn.weight / torch.sqrt(bn.running_var + bn.eps)
        fused = nn.Conv2d(conv.in_channels, conv.out_channels, conv.kernel_size, conv.stride,
                          conv.padding, groups=conv.groups, bias=True).to(conv.weight.device)
        fused.weight.copy_(conv.weight * factor[:, None, None, None])
        fused.bias.copy_(bn.bias - bn.running_mean * factor)
        self.conv, self.bn = fused, nn.Identity()


def fuse_model(model: nn.Module) -> nn.Module:
    """Fold every Conv's BatchNorm in place (call on an eval-mode model); returns it."""
    for m in model.modules():
        if isinstance(m, Conv):
            m.fuse()
    return model


class Bottleneck(nn.Module):
    """Two 3x3 Convs with an optional residual (only when c_in == c_out)."""

    def __init__(self, c_in: int, c_out: int, shortcut: bool = True, expansion: float = 0.5):
        super().__init__()
        hidden = int(c_out * expansion)
        self.cv1 = Conv(c_in, hidden, 3)
        self.cv2 = Conv(hidden, c_out, 3)
        self.add = shortcut and c_in == c_out

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.cv2(self.cv1(x))
        return x + y if self.add else y


class C2f(nn.Module):
    """CSP stage with two splits and n bottlenecks whose outputs are all concatenated.

    A 1x1 conv makes 2*h channels, split in two halves; the second half passes
    n bottlenecks in a chain and every intermediate result is kept; a final
    1x1 conv fuses the (2 + n) * h channels to c_out.
    """

    def __init__(self, c_in: int, c_out: int, n: int = 1, shortcut: bool = False, expansion: float = 0.5):
        super().__init__()
        self.hidden = int(c_out * expansion)
        self.cv1 = Conv(c_in, 2 * self.hidden, 1)
        self.cv2 = Conv((2 + n) * self.hidden, c_out, 1)
        self.m = nn.ModuleList(Bottleneck(self.hidden, self.hidden, shortcut, expansion=1.0) for _ in range(n))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        parts = list(self.cv1(x).chunk(2, dim=1))
        for block in self.m:
            parts.append(block(parts[-1]))
        return self.cv2(torch.cat(parts, dim=1))


class SPPF(nn.Module):
    """Spatial pyramid pooling (fast): three chained k x k max-pools, concatenated."""

    def __init__(self, c_in: int, c_out: int, k: int = 5):
        super().__init__()
        hidden = c_in // 2
        self.cv1 = Conv(c_in, hidden, 1)
        self.cv2 = Conv(hidden * 4, c_out, 1)
        self.pool = nn.MaxPool2d(kernel_size=k, stride=1, padding=k // 2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = self.cv1(x)
        y1 = self.pool(x)
        y2 = self.pool(y1)
        return self.cv2(torch.cat((x, y1, y2, self.pool(y2)), dim=1))


class Concat(nn.Module):
    """Concatenate a list of tensors along channels."""

    def forward(self, xs: Sequence[torch.Tensor]) -> torch.Tensor:
        return torch.cat(list(xs), dim=1)


def stage_widths(width_multiple: float, max_channels: int = 1024) -> Tuple[int, ...]:
    """Channel counts of P1..P5 for a width multiplier."""
    return tuple(scale_width(c, width_multiple, max_channels) for c in BASE_WIDTHS)


class Backbone(nn.Module):
    """CSP-Darknet backbone (YOLOv8): returns the stride 8, 16 and 32 feature maps."""

    def __init__(self, width_multiple: float, depth_multiple: float, max_channels: int = 1024):
        super().__init__()
        w = stage_widths(width_multiple, max_channels)
        d = [scale_depth(n, depth_multiple) for n in BASE_DEPTHS]
        self.stem = Conv(3, w[0], 3, 2)                                            # stride 2
        self.stage2 = nn.Sequential(Conv(w[0], w[1], 3, 2), C2f(w[1], w[1], d[0], True))  # 4
        self.stage3 = nn.Sequential(Conv(w[1], w[2], 3, 2), C2f(w[2], w[2], d[1], True))  # 8
        self.stage4 = nn.Sequential(Conv(w[2], w[3], 3, 2), C2f(w[3], w[3], d[2], True))  # 16
        self.stage5 = nn.Sequential(Conv(w[3], w[4], 3, 2), C2f(w[4], w[4], d[3], True),
                                    SPPF(w[4], w[4], 5))                                # 32
        self.out_channels = (w[2], w[3], w[4])

    def forward(self, x: torch.Tensor) -> List[torch.Tensor]:
        p3 = self.stage3(self.stage2(self.stem(x)))
        p4 = self.stage4(p3)
        p5 = self.stage5(p4)
        return [p3, p4, p5]


class PANNeck(nn.Module):
    """YOLOv8 PAN neck: top-down (upsample + concat + C2f) then bottom-up (strided conv).

    Input and output: [P3, P4, P5] at strides 8, 16, 32 with the backbone's widths.
    """

    def __init__(self, channels: Tuple[int, int, int], depth_multiple: float):
        super().__init__()
        c3, c4, c5 = channels
        n = scale_depth(3, depth_multiple)
        self.up = nn.Upsample(scale_factor=2, mode="nearest")
        self.cat = Concat()
        self.td4 = C2f(c5 + c4, c4, n)
        self.td3 = C2f(c4 + c3, c3, n)
        self.down3 = Conv(c3, c3, 3, 2)
        self.bu4 = C2f(c3 + c4, c4, n)
        self.down4 = Conv(c4, c4, 3, 2)
        self.bu5 = C2f(c4 + c5, c5, n)
        self.out_channels = (c3, c4, c5)

    def forward(self, feats: List[torch.Tensor]) -> List[torch.Tensor]:
        p3, p4, p5 = feats
        t4 = self.td4(self.cat([self.up(p5), p4]))
        n3 = self.td3(self.cat([self.up(t4), p3]))
        n4 = self.bu4(self.cat([self.down3(n3), t4]))
        n5 = self.bu5(self.cat([self.down4(n4), p5]))
        return [n3, n4, n5]
