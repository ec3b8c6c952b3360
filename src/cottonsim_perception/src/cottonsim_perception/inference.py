"""Run a trained Cotton-Eye network on camera frames.

:class:`Predictor` loads a checkpoint (see ``nn.models``), letterboxes an RGB
frame to the network input, runs the network on the CPU (or a given device)
and returns :class:`~cottonsim_perception.types.Detections` in the frame's own
pixels. For inference the BatchNorms are folded into the convolutions and,
with ``optimize`` (the default), the network runs as a frozen channels-last
TorchScript graph (``nn.optimize``; same outputs up to float rounding).

:func:`class_masks` merges the instance masks of a scene segmentation into one
mask per class (what row centring needs: the ground and sky regions).
"""
from __future__ import annotations

import warnings
from typing import Dict, NamedTuple, Optional, Tuple

import numpy as np
import torch

from .nn.blocks import fuse_model
from .nn.letterbox import LetterboxTransform, letterbox
from .nn.models import load_model
from .nn.optimize import freeze_for_inference
from .nn.postprocess import PostprocessConfig, postprocess
from .types import Detections


def check_image(image_rgb: np.ndarray) -> None:
    """Raise ValueError unless the image is a non-empty (H, W, 3) uint8 array."""
    if not isinstance(image_rgb, np.ndarray):
        raise ValueError(f"image must be a numpy array, got {type(image_rgb).__name__}")
    if image_rgb.dtype != np.uint8:
        raise ValueError(f"image must be uint8, got {image_rgb.dtype}")
    if image_rgb.ndim != 3 or image_rgb.shape[2] != 3:
        raise ValueError(f"image must be (H, W, 3) RGB, got shape {image_rgb.shape}")
    if image_rgb.shape[0] < 2 or image_rgb.shape[1] < 2:
        raise ValueError(f"image is empty or too small: shape {image_rgb.shape}")


class Predictor:
    """A loaded network plus its pre- and post-processing.

    weights_path: checkpoint written by ``train`` / ``save_checkpoint``;
    device: torch device string; conf_threshold: minimum class probability
    (0..1); iou_threshold: NMS IoU (0..1); threads: torch CPU threads (None
    leaves torch's setting; note it is process-wide); optimize: run the
    network as a frozen channels-last TorchScript graph (``nn.optimize``;
    False runs the fused eager model, e.g. to compare); mask_threshold: mask
    pixel probability threshold (0..1); None (default) = the value calibrated
    for these weights and stored in the checkpoint (``scripts/calibrate_mask_threshold``),
    else PostprocessConfig's 0.5; flip_tta: detector only, also run the network on
    the left-right mirrored input and merge both sets of boxes in one NMS
    (test-time augmentation; twice the network time).
    ``model`` is the fused network (for introspection), ``network(x)`` what
    ``predict`` runs on a letterboxed (1, 3, H, W) float 0..1 tensor.
    Raises FileNotFoundError / ValueError for missing or invalid weights.
    """

    def __init__(self, weights_path: str, device: str = "cpu", conf_threshold: float = 0.25,
                 iou_threshold: float = 0.7, threads: Optional[int] = None, optimize: bool = True,
                 mask_threshold: Optional[float] = None, flip_tta: bool = False):
        if threads is not None:
            if not isinstance(threads, int) or threads < 1:
                raise ValueError(f"threads must be a positive int or None, got {threads!r}")
            torch.set_num_threads(threads)
        self.device = torch.device(device)
        loaded = load_model(weights_path, self.device)
        if mask_threshold is None:
            mask_threshold = loaded.inference.get("mask_threshold", PostprocessConfig.mask_threshold)
        self.post_config = PostprocessConfig(conf_threshold=float(conf_threshold),
                                             iou_threshold=float(iou_threshold),
                                             mask_threshold=float(mask_threshold))
        self.model = fuse_model(loaded)
        self.config = self.model.config
        self.class_names = self.config.class_names
        if flip_tta and self.config.task != "det":
            raise ValueError(f"flip_tta is for detectors only; {weights_path} is a {self.config.task} network")
        self.flip_tta = bool(flip_tta)
        self._network = self.model
        self.optimized = False
        if optimize:
            try:
                self._network = freeze_for_inference(self.model, self.config.input_height, self.config.input_width)
                self.optimized = True
            except (RuntimeError, AttributeError) as exc:   # a torch without TorchScript: stay eager
                warnings.warn(f"Predictor: frozen TorchScript unavailable ({exc}); running the eager model")

    def network(self, x: torch.Tensor):
        """The network's eval-mode output for a letterboxed (1, 3, H, W) float 0..1 input."""
        with torch.inference_mode():
            return self._network(x)

    @property
    def task(self) -> str:
        return self.config.task

    def predict(self, image_rgb: np.ndarray) -> Detections:
        """Detections of one (H, W, 3) uint8 RGB frame, in its own pixels."""
        return self.decode(self.forward(image_rgb))

    def forward(self, image_rgb: np.ndarray) -> "NetworkOutput":
        """The network's raw output for one frame (CPU tensors), before any threshold.

        ``decode`` turns it into Detections with the current ``post_config``,
        so a caller that tries several thresholds (``calibrate_mask_threshold``)
        runs the network once per frame.
        """
        check_image(image_rgb)
        img, tf = letterbox(image_rgb, self.config.input_width, self.config.input_height)
        # (H, W, 3) uint8 viewed as (1, 3, H, W): already channels-last, no copy before the float cast
        x = torch.from_numpy(img).to(self.device).permute(2, 0, 1)[None]
        if not self.optimized:
            x = x.contiguous()      # the eager model keeps NCHW weights
        x = x.float().div_(255.0)
        with torch.inference_mode():
            out = self._network(x)
            if self.config.task == "seg":
                detail = out[2].float().cpu() if len(out) > 2 else None      # proto_stride 1
                return NetworkOutput(out[0].float().cpu(), out[1].float().cpu(), detail, tf)
            predictions = out.float().cpu()
            if self.flip_tta:
                predictions = torch.cat([predictions, self._mirrored_predictions(x)], dim=1)
            return NetworkOutput(predictions, None, None, tf)

    def _mirrored_predictions(self, x: torch.Tensor) -> torch.Tensor:
        """Detector output for the left-right mirror of the letterboxed input ``x``, with its
        boxes mirrored back into ``x``'s pixels (x1' = W - x2, x2' = W - x1)."""
        mirrored = self._network(x.flip(-1)).float().cpu()
        width = float(self.config.input_width)
        x1 = width - mirrored[..., 2]
        x2 = width - mirrored[..., 0]
        mirrored[..., 0] = x1
        mirrored[..., 2] = x2
        return mirrored

    def decode(self, output: "NetworkOutput") -> Detections:
        """Detections in the frame's pixels from ``forward``'s output (thresholds: ``post_config``)."""
        with torch.inference_mode():
            return postprocess(output.predictions, self.config.num_classes, [output.transform],
                               output.prototypes, self.post_config, output.detail)[0]


class NetworkOutput(NamedTuple):
    """One frame's raw network output (CPU tensors) and its letterbox transform.

    predictions: (1, anchors, 4 + classes [+ mask coefficients ...]); prototypes:
    the segmenter's mask prototypes (None for the detector); detail: the
    full-resolution detail features of a ``proto_stride`` 1 segmenter, else None.
    """

    predictions: torch.Tensor
    prototypes: Optional[torch.Tensor]
    detail: Optional[torch.Tensor]
    transform: LetterboxTransform


def class_masks(detections: Detections, shape: Tuple[int, int],
                num_classes: Optional[int] = None) -> Dict[int, np.ndarray]:
    """Union of the instance masks of each class: class id -> (H, W) bool.

    shape: (H, W) of the frame. Classes without instances map to an all-False
    mask when ``num_classes`` is given (ids 0..num_classes-1), otherwise only
    the classes present appear. Raises ValueError for box-only detections or
    masks of another size.
    """
    h, w = int(shape[0]), int(shape[1])
    if detections.masks is None:
        raise ValueError("class_masks needs segmentation detections (masks is None)")
    if len(detections) and detections.masks.shape[1:] != (h, w):
        raise ValueError(f"masks are {detections.masks.shape[1:]}, expected {(h, w)}")
    ids = range(num_classes) if num_classes is not None else sorted(set(detections.classes.tolist()))
    out = {int(c): np.zeros((h, w), dtype=bool) for c in ids}
    for c, m in zip(detections.classes.tolist(), detections.masks):
        if c in out:
            out[c] |= m
        else:
            out[c] = m.copy()
    return out
