"""Letterbox resize (keep aspect ratio, pad) and the inverse mapping.

The networks take a fixed input size (e.g. 320 x 256 px) while the cameras give
640 x 480 or 720 x 540 px. A letterbox scales the image uniformly so that it
fits, centres it and fills the rest with grey (114), so objects keep their
shape. :class:`LetterboxTransform` remembers the scale and padding so boxes and
masks predicted on the network input can be mapped back to the original image.

Convention: pixel-edge coordinates, x right, y down; a point x in the original
image lands at ``x * scale_x + pad_left`` in the network input.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import cv2
import numpy as np
import torch

PAD_VALUE = 114


#: one instance's soft mask inside its box: ((r0, r1, c0, c1) mask-pixel window, (r1 - r0, c1 - c0) values)
MaskWindow = Tuple[Tuple[int, int, int, int], torch.Tensor]


def dense_masks(windows: Sequence[Optional[MaskWindow]], height: int, width: int,
                dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """(n, height, width) masks from per-instance windows (None: an empty mask; 0 outside the windows)."""
    out = torch.zeros((len(windows), height, width), dtype=dtype)
    for i, item in enumerate(windows):
        if item is not None:
            (r0, r1, c0, c1), soft = item
            out[i, r0:r1, c0:c1] = soft
    return out


@dataclass(frozen=True)
class LetterboxTransform:
    """Geometry of one letterbox: original (src) -> network input (dst) pixels.

    src_width/src_height: original image size [px]; dst_width/dst_height:
    network input size [px]; scale_x/scale_y: resize factors (equal up to
    rounding of the resized size); pad_left/pad_top: offset of the resized
    image inside the input [px]; content_width/content_height: resized size [px].
    """

    src_width: int
    src_height: int
    dst_width: int
    dst_height: int
    content_width: int
    content_height: int
    pad_left: int
    pad_top: int

    def __post_init__(self) -> None:
        for name in ("src_width", "src_height", "dst_width", "dst_height",
                     "content_width", "content_height"):
            if int(getattr(self, name)) <= 0:
                raise ValueError(f"LetterboxTransform.{name} must be > 0")
        if self.content_width + self.pad_left > self.dst_width or \
                self.content_height + self.pad_top > self.dst_height:
            raise ValueError("LetterboxTransform: content plus padding exceeds the destination size")

    @property
    def scale_x(self) -> float:
        return self.content_width / self.src_width

    @property
    def scale_y(self) -> float:
        return self.content_height / self.src_height

    @staticmethod
    def fit(src_width: int, src_height: int, dst_width: int, dst_height: int) -> "LetterboxTransform":
        """The centred, aspect-keeping fit of a src image into dst."""
        if src_width <= 0 or src_height <= 0:
            raise ValueError(f"letterbox: source size must be positive, got {src_width}x{src_height}")
        if dst_width <= 0 or dst_height <= 0:
            raise ValueError(f"letterbox: destination size must be positive, got {dst_width}x{dst_height}")
        scale = min(dst_width / src_width, dst_height / src_height)
        cw = min(dst_width, max(1, int(round(src_width * scale))))
        ch = min(dst_height, max(1, int(round(src_height * scale))))
        return LetterboxTransform(int(src_width), int(src_height), int(dst_width), int(dst_height),
                                  cw, ch, (dst_width - cw) // 2, (dst_height - ch) // 2)

    def affine(self) -> np.ndarray:
        """The 2x3 float64 matrix mapping src pixels to dst pixels."""
        return np.array([[self.scale_x, 0.0, self.pad_left],
                         [0.0, self.scale_y, self.pad_top]], dtype=np.float64)

    def boxes_to_original(self, boxes_xyxy: np.ndarray) -> np.ndarray:
        """Map (N, 4) boxes from network-input to original pixels, clipped to the image."""
        b = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4).copy()
        b[:, [0, 2]] = (b[:, [0, 2]] - self.pad_left) / self.scale_x
        b[:, [1, 3]] = (b[:, [1, 3]] - self.pad_top) / self.scale_y
        b[:, [0, 2]] = b[:, [0, 2]].clip(0, self.src_width)
        b[:, [1, 3]] = b[:, [1, 3]].clip(0, self.src_height)
        return b

    def content_on_grid(self, height: int, width: int) -> Tuple[float, float, float, float]:
        """The content region (x0, y0, x1, y1) on a (height, width) grid proportional to the network
        input [grid px, may be fractional]."""
        fx, fy = width / self.dst_width, height / self.dst_height
        return (self.pad_left * fx, self.pad_top * fy,
                (self.pad_left + self.content_width) * fx, (self.pad_top + self.content_height) * fy)

    def masks_to_original(self, masks: torch.Tensor, threshold: float = 0.5) -> np.ndarray:
        """Map (N, h, w) soft masks (values 0..1) on the network input grid back.

        The masks may be at any resolution proportional to the input (e.g. the
        prototype grid, a quarter of the input): the content region is cut out,
        resized bilinearly (half-pixel centres, edges clamped, as torch's
        ``interpolate(..., align_corners=False)``) to the original size, then
        thresholded. Returns (N, src_height, src_width) bool.
        """
        if masks.ndim != 3:
            raise ValueError(f"masks must be (N, h, w), got shape {tuple(masks.shape)}")
        n, h, w = masks.shape
        if n == 0:
            return np.zeros((0, self.src_height, self.src_width), dtype=bool)
        x0, y0, x1, y1 = self.content_on_grid(h, w)
        ix0, iy0 = int(np.floor(x0)), int(np.floor(y0))
        ix1, iy1 = int(np.ceil(x1)), int(np.ceil(y1))
        crop = np.ascontiguousarray(masks[:, iy0:iy1, ix0:ix1].float().cpu().numpy())
        # Resize the integer-pixel crop, then cut the exact (fractional) content window.
        ox = int(round((x0 - ix0) / (x1 - x0) * self.src_width))
        oy = int(round((y0 - iy0) / (y1 - y0) * self.src_height))
        big_w = max(int(round((ix1 - ix0) / (x1 - x0) * self.src_width)), ox + self.src_width)
        big_h = max(int(round((iy1 - iy0) / (y1 - y0) * self.src_height)), oy + self.src_height)
        out = np.empty((n, self.src_height, self.src_width), dtype=bool)
        for i in range(n):
            # cv2's bilinear (half-pixel centres, edge clamped) = torch's align_corners=False,
            # several times faster on one core; only float rounding differs.
            up = cv2.resize(crop[i], (big_w, big_h), interpolation=cv2.INTER_LINEAR)
            np.greater(up[oy:oy + self.src_height, ox:ox + self.src_width], threshold, out=out[i])
        return out

    def window_masks_to_original(self, windows: Sequence[Optional[MaskWindow]], height: int, width: int,
                                 threshold: float = 0.5) -> np.ndarray:
        """:meth:`masks_to_original` of masks given as per-instance windows.

        windows: per instance None (an empty mask) or ``((r0, r1, c0, c1),
        soft)``, the (r1 - r0, c1 - c0) soft values of a mask that is 0
        outside that window, on a (height, width) mask grid proportional to
        the network input (``postprocess.box_soft_mask_windows``).

        When the mask grid maps onto the original image by whole factors and
        the content starts on a whole mask pixel (640x480 frames in a 640x512
        or 320x256 input, masks at a quarter or half of it), each window,
        with a margin of one pixel of zeros, is resized on its own: the
        bilinear value of a pixel depends only on its two neighbours in each
        direction, which inside the margin are the same as in the whole
        mask, and beyond the margin the whole mask's value is 0. So the
        result equals :meth:`masks_to_original` of the dense masks, for the
        pixels of the windows only. Otherwise the dense masks are built and
        mapped by :meth:`masks_to_original`. Returns (N, src_height, src_width) bool.
        """
        n = len(windows)
        x0, y0, x1, y1 = self.content_on_grid(height, width)
        cw, ch = x1 - x0, y1 - y0                                             # content size [mask px]
        sx, sy = self.src_width / cw, self.src_height / ch                    # mask px -> original px
        whole = all(float(v).is_integer() for v in (x0, y0, cw, ch, sx, sy))
        if n == 0 or not whole:
            return self.masks_to_original(dense_masks(windows, height, width), threshold)
        ix0, iy0, iw, ih, kx, ky = (int(v) for v in (x0, y0, cw, ch, sx, sy))
        out = np.zeros((n, self.src_height, self.src_width), dtype=bool)
        for i, item in enumerate(windows):
            if item is None:
                continue
            (r0, r1, c0, c1), soft = item
            # the window in content coordinates, plus a margin of 1 px, clipped to the content
            a_r, b_r = max(r0 - iy0 - 1, 0), min(r1 - iy0 + 1, ih)
            a_c, b_c = max(c0 - ix0 - 1, 0), min(c1 - ix0 + 1, iw)
            # the part of the window inside the content
            p_r0, p_r1 = max(r0 - iy0, 0), min(r1 - iy0, ih)
            p_c0, p_c1 = max(c0 - ix0, 0), min(c1 - ix0, iw)
            if p_r0 >= p_r1 or p_c0 >= p_c1:
                continue
            patch = np.zeros((b_r - a_r, b_c - a_c), dtype=np.float32)
            patch[p_r0 - a_r:p_r1 - a_r, p_c0 - a_c:p_c1 - a_c] = soft.float().cpu().numpy()[
                p_r0 + iy0 - r0:p_r1 + iy0 - r0, p_c0 + ix0 - c0:p_c1 + ix0 - c0]
            up = cv2.resize(patch, ((b_c - a_c) * kx, (b_r - a_r) * ky), interpolation=cv2.INTER_LINEAR)
            np.greater(up, threshold, out=out[i, a_r * ky:b_r * ky, a_c * kx:b_c * kx])
        return out


def letterbox(image: np.ndarray, dst_width: int, dst_height: int,
              pad_value: int = PAD_VALUE) -> Tuple[np.ndarray, LetterboxTransform]:
    """Resize an (H, W, C) uint8 image into dst size keeping aspect; pad with grey.

    Returns the (dst_height, dst_width, C) image and its transform.
    """
    if not isinstance(image, np.ndarray) or image.ndim != 3 or image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"letterbox: expected an (H, W, C) image, got "
                         f"{getattr(image, 'shape', type(image))}")
    t = LetterboxTransform.fit(image.shape[1], image.shape[0], dst_width, dst_height)
    if (t.content_width, t.content_height) != (image.shape[1], image.shape[0]):
        interp = cv2.INTER_AREA if t.scale_x < 1.0 else cv2.INTER_LINEAR
        resized = cv2.resize(image, (t.content_width, t.content_height), interpolation=interp)
    else:
        resized = image
    if resized.ndim == 2:
        resized = resized[:, :, None]
    out = np.full((dst_height, dst_width, image.shape[2]), pad_value, dtype=image.dtype)
    out[t.pad_top:t.pad_top + t.content_height, t.pad_left:t.pad_left + t.content_width] = resized
    return out, t
