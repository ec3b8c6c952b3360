"""Run a trained Cotton-Eye network on camera frames.

:class:`Predictor` loads a checkpoint (see ``nn.models``), letterboxes RGB
frames to the network input, runs the network with one of the backends of
``nn.backends`` (ONNX Runtime on the checkpoint's ``.onnx`` export, or torch)
and returns :class:`~cottonsim_perception.types.Detections` in each frame's
own pixels. For inference the BatchNorms are folded into the convolutions;
the torch backend with ``optimize`` (the default) runs a frozen
channels-last TorchScript graph (``nn.optimize``; same outputs up to float
rounding).

:func:`class_masks` merges the instance masks of a scene segmentation into one
mask per class (what row centring needs: the ground and sky regions).
"""
from __future__ import annotations

import os
from typing import Dict, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np
import torch

from .nn.backends import OnnxRuntimeBackend, TorchBackend, check_backend_name
from .nn.blocks import fuse_model
from .nn.letterbox import LetterboxTransform, letterbox
from .nn.models import load_model
from .nn.onnx_export import check_export_matches, onnx_path_for
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
    (0..1); iou_threshold: NMS IoU (0..1); threads: CPU threads of the
    forward pass (None leaves the backend's default; for torch it is
    process-wide); optimize: torch backend only, run the network as a frozen
    channels-last TorchScript graph (``nn.optimize``; False runs the fused
    eager model, e.g. to compare); mask_threshold: mask pixel probability
    threshold (0..1); None (default) = the value calibrated for these weights
    and stored in the checkpoint (``scripts/calibrate_mask_threshold``), else
    PostprocessConfig's 0.5; flip_tta: detector only, also run the network on
    the left-right mirrored input and merge both sets of boxes in one NMS
    (test-time augmentation; twice the network time); backend: 'torch'
    (default here) or 'onnxruntime' (``nn.backends``: runs ``onnx_path``,
    default the ``.onnx`` file beside the checkpoint, which must be exported
    from these weights).
    ``model`` is the fused network (for introspection), ``network(x)`` what
    the backend runs on a letterboxed (1, 3, H, W) float 0..1 tensor.
    Raises FileNotFoundError / ValueError for missing or invalid weights or export.
    """

    def __init__(self, weights_path: str, device: str = "cpu", conf_threshold: float = 0.25,
                 iou_threshold: float = 0.7, threads: Optional[int] = None, optimize: bool = True,
                 mask_threshold: Optional[float] = None, flip_tta: bool = False, backend: str = "torch",
                 onnx_path: Optional[str] = None):
        check_backend_name(backend)
        if threads is not None and (not isinstance(threads, int) or threads < 1):
            raise ValueError(f"threads must be a positive int or None, got {threads!r}")
        if threads is not None and backend == "torch":
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
        h, w = self.config.input_height, self.config.input_width
        if backend == "onnxruntime":
            if self.device.type != "cpu":
                raise ValueError(f"the onnxruntime backend runs on the CPU, not on device '{device}'")
            onnx_path = onnx_path or onnx_path_for(weights_path)
            if not os.path.isfile(onnx_path):
                raise FileNotFoundError(f"no ONNX export '{onnx_path}' of '{weights_path}' "
                                        f"(make it with scripts/export_onnx {weights_path})")
            self.backend = OnnxRuntimeBackend(onnx_path, h, w, threads=threads)
            check_export_matches(self.backend.metadata, weights_path, onnx_path)
        else:
            self.backend = TorchBackend(self.model, h, w, optimize=optimize)
        self.optimized = getattr(self.backend, "optimized", False)

    def network(self, x: torch.Tensor):
        """The network's eval-mode output for a letterboxed (1, 3, H, W) float 0..1 input."""
        if isinstance(self.backend, TorchBackend):
            with torch.inference_mode():
                return self.backend.network(x)
        images = (x.detach().cpu().permute(0, 2, 3, 1) * 255.0).round().clamp(0, 255).to(torch.uint8).numpy()
        out = tuple(torch.from_numpy(o) for o in self.backend.run(images))
        return out[0] if len(out) == 1 else out

    @property
    def task(self) -> str:
        return self.config.task

    def predict(self, image_rgb: np.ndarray) -> Detections:
        """Detections of one (H, W, 3) uint8 RGB frame, in its own pixels."""
        return self.decode(self.forward(image_rgb))

    def predict_batch(self, images_rgb: Sequence[np.ndarray]) -> List[Detections]:
        """Detections of several frames (one forward pass of the backend), each in its own pixels."""
        return [self.decode(o) for o in self.forward_batch(images_rgb)]

    def forward(self, image_rgb: np.ndarray) -> "NetworkOutput":
        """The network's raw output for one frame (CPU tensors), before any threshold.

        ``decode`` turns it into Detections with the current ``post_config``,
        so a caller that tries several thresholds (``calibrate_mask_threshold``)
        runs the network once per frame.
        """
        return self.forward_batch([image_rgb])[0]

    def forward_batch(self, images_rgb: Sequence[np.ndarray]) -> List["NetworkOutput"]:
        """``forward`` of each frame, the letterboxed frames run as one batch."""
        if len(images_rgb) == 0:
            raise ValueError("forward_batch needs at least one image")
        boxed, transforms = [], []
        for image in images_rgb:
            check_image(image)
            img, tf = letterbox(image, self.config.input_width, self.config.input_height)
            boxed.append(img)
            transforms.append(tf)
        batch = np.stack(boxed)
        out = [torch.from_numpy(o) for o in self.backend.run(batch)]
        if self.config.task == "seg":
            detail = out[2] if len(out) > 2 else None      # proto_stride 1
            return [NetworkOutput(out[0][b:b + 1], out[1][b:b + 1],
                                  None if detail is None else detail[b:b + 1], tf)
                    for b, tf in enumerate(transforms)]
        predictions = out[0]
        if self.flip_tta:
            predictions = torch.cat([predictions, self._mirrored_predictions(batch)], dim=1)
        return [NetworkOutput(predictions[b:b + 1], None, None, tf) for b, tf in enumerate(transforms)]

    def _mirrored_predictions(self, batch: np.ndarray) -> torch.Tensor:
        """Detector output for the left-right mirror of the letterboxed frames, with its
        boxes mirrored back into their pixels (x1' = W - x2, x2' = W - x1)."""
        mirrored = torch.from_numpy(self.backend.run(np.ascontiguousarray(batch[:, :, ::-1]))[0])
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
