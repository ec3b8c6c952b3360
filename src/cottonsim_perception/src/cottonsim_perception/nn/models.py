"""The two Cotton-Eye networks, their configuration and checkpoint files.

* :class:`YoloSegmenter` - YOLOv8-seg-style instance segmentation of the farm
  scene (0 cotton plants, 1 ground, 2 sky), used for row centring.
* :class:`YoloDetector` - YOLOv8-style detector of cotton bolls (class 0).

Both are backbone -> PAN neck -> head (see ``blocks`` and ``heads``). In train
mode ``forward`` returns the raw head outputs the loss needs; in eval mode it
returns decoded predictions (boxes in network-input pixels, class
probabilities, and for segmentation the mask coefficients and prototypes) that
``postprocess`` turns into :class:`~cottonsim_perception.types.Detections`.

Checkpoints are plain ``torch.save`` dicts that ``torch.load(weights_only=True)``
accepts: ``{'format', 'format_version', 'model_config' (dict), 'state_dict',
'train' (dict: epochs, data, seed, metrics, ...), 'optimizer' (optional)}``.
"""
from __future__ import annotations

import os
from dataclasses import asdict, dataclass, replace
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import torch
import torch.nn as nn

from .blocks import Backbone, PANNeck
from .heads import PROTO_STRIDES, STRIDES, DetectHead, SegmentHead

CHECKPOINT_FORMAT = "cottonsim_yolo"
CHECKPOINT_VERSION = 1
TASKS = ("seg", "det")


@dataclass(frozen=True)
class ModelConfig:
    """Architecture and input geometry of one network.

    task: 'seg' (instance segmentation) or 'det' (boxes only).
    num_classes, class_names: class count and one name per class.
    input_width / input_height: network input size [px], multiples of 32
        (camera frames are letterboxed into it).
    width_multiple / depth_multiple: YOLOv8 scaling (n = 0.25 / 0.33).
    max_channels: channel cap before the width multiplier.
    reg_max: DFL bins per box side (max distance reg_max - 1 grid cells).
    num_prototypes / proto_channels: mask prototypes and Proto hidden width
        (segmentation only).
    proto_stride: network-input pixels per prototype pixel, 4 (YOLOv8), 2
        (one more upsampling stage: finer masks) or 1 (masks at the full
        input, with a detail path from the input image for thin stems; see
        ``heads.Proto``); segmentation only.
    detail_channels: width of that full-resolution detail path (used only
        with proto_stride 1; it is the costly part there, 8 is cheap).
    The defaults are the CPU-sized scene segmenter; see :meth:`boll_detector`.
    """

    task: str = "seg"
    num_classes: int = 3
    class_names: Tuple[str, ...] = ("cotton_plant", "ground", "sky")
    input_width: int = 320
    input_height: int = 256
    width_multiple: float = 0.125
    depth_multiple: float = 0.33
    max_channels: int = 1024
    reg_max: int = 16
    num_prototypes: int = 16
    proto_channels: int = 32
    proto_stride: int = 4
    detail_channels: int = 8

    def __post_init__(self) -> None:
        if self.task not in TASKS:
            raise ValueError(f"ModelConfig.task must be one of {TASKS}, got {self.task!r}")
        if not isinstance(self.num_classes, int) or self.num_classes < 1:
            raise ValueError(f"ModelConfig.num_classes must be a positive int, got {self.num_classes!r}")
        object.__setattr__(self, "class_names", tuple(str(n) for n in self.class_names))
        if len(self.class_names) != self.num_classes:
            raise ValueError(f"ModelConfig.class_names must have num_classes={self.num_classes} "
                             f"entries, got {len(self.class_names)}")
        for name in ("input_width", "input_height"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 32 or v % 32:
                raise ValueError(f"ModelConfig.{name} must be a positive multiple of 32 px, got {v!r}")
        if not 0.0 < self.width_multiple <= 2.0:
            raise ValueError(f"ModelConfig.width_multiple must be in (0, 2], got {self.width_multiple}")
        if not 0.0 < self.depth_multiple <= 2.0:
            raise ValueError(f"ModelConfig.depth_multiple must be in (0, 2], got {self.depth_multiple}")
        if not isinstance(self.max_channels, int) or self.max_channels < 8:
            raise ValueError(f"ModelConfig.max_channels must be an int >= 8, got {self.max_channels!r}")
        if not isinstance(self.reg_max, int) or self.reg_max < 2:
            raise ValueError(f"ModelConfig.reg_max must be an int >= 2, got {self.reg_max!r}")
        if not isinstance(self.num_prototypes, int) or self.num_prototypes < 1:
            raise ValueError(f"ModelConfig.num_prototypes must be a positive int, got {self.num_prototypes!r}")
        if not isinstance(self.proto_channels, int) or self.proto_channels < 1:
            raise ValueError(f"ModelConfig.proto_channels must be a positive int, got {self.proto_channels!r}")
        if self.proto_stride not in PROTO_STRIDES:
            raise ValueError(f"ModelConfig.proto_stride must be one of {PROTO_STRIDES}, got {self.proto_stride!r}")
        if not isinstance(self.detail_channels, int) or isinstance(self.detail_channels, bool) \
                or not 1 <= self.detail_channels <= 64:
            raise ValueError(f"ModelConfig.detail_channels must be an int in [1, 64], got {self.detail_channels!r}")

    @staticmethod
    def scene_segmenter(**overrides: Any) -> "ModelConfig":
        """The default scene segmenter (3 classes, 320x256 input, width 0.125)."""
        return replace(ModelConfig(), **overrides)

    @staticmethod
    def boll_detector(**overrides: Any) -> "ModelConfig":
        """The default boll detector (1 class, 640x480 input keeps bolls >= ~9 px, width 0.25)."""
        base = replace(ModelConfig(), task="det", num_classes=1, class_names=("cotton_boll",),
                       input_width=640, input_height=480, width_multiple=0.25)
        return replace(base, **overrides)

    def to_dict(self) -> Dict[str, Any]:
        """Plain dict (lists, not tuples) for checkpoints and YAML."""
        d = asdict(self)
        d["class_names"] = list(self.class_names)
        return d

    @staticmethod
    def from_dict(d: Dict[str, Any]) -> "ModelConfig":
        """Inverse of :meth:`to_dict`; unknown keys raise ValueError."""
        known = set(ModelConfig.__dataclass_fields__)
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"ModelConfig: unknown keys {sorted(unknown)}")
        d = dict(d)
        if "class_names" in d:
            d["class_names"] = tuple(d["class_names"])
        return ModelConfig(**d)


class _YoloBase(nn.Module):
    """Backbone + neck shared by both networks; ``self.config`` describes it."""

    def __init__(self, config: ModelConfig):
        super().__init__()
        self.config = config
        self.strides = STRIDES
        self.backbone = Backbone(config.width_multiple, config.depth_multiple, config.max_channels)
        self.neck = PANNeck(self.backbone.out_channels, config.depth_multiple)

    def features(self, images: torch.Tensor):
        if images.ndim != 4 or images.shape[1] != 3:
            raise ValueError(f"expected images of shape (B, 3, H, W), got {tuple(images.shape)}")
        if images.shape[2] % 32 or images.shape[3] % 32:
            raise ValueError(f"image height and width must be multiples of 32, got {tuple(images.shape[2:])}")
        return self.neck(self.backbone(images))


class YoloDetector(_YoloBase):
    """YOLOv8-style box detector.

    forward(images (B, 3, H, W) float 0..1):
      train mode -> list of 3 level maps (B, 4 * reg_max + nc, H/s, W/s);
      eval mode  -> (B, A, 4 + nc): boxes xyxy [input px], class probabilities.
    """

    def __init__(self, num_classes: int = 1, width_multiple: float = 0.25, depth_multiple: float = 0.33,
                 config: Optional[ModelConfig] = None, **config_overrides: Any):
        if config is None:
            names = config_overrides.pop("class_names", tuple(f"class{i}" for i in range(num_classes)))
            config = ModelConfig.boll_detector(num_classes=num_classes, class_names=names,
                                               width_multiple=width_multiple, depth_multiple=depth_multiple,
                                               **config_overrides)
        if config.task != "det":
            raise ValueError(f"YoloDetector needs a config with task 'det', got {config.task!r}")
        super().__init__(config)
        self.head = DetectHead(config.num_classes, self.neck.out_channels, config.reg_max, self.strides)

    def raw(self, images: torch.Tensor):
        """Train-style output in any mode (validation loss with eval-mode BatchNorm)."""
        return self.head(self.features(images))

    def forward(self, images: torch.Tensor):
        maps = self.raw(images)
        return maps if self.training else self.head.decode(maps)


class YoloSegmenter(_YoloBase):
    """YOLOv8-seg-style instance segmenter.

    forward(images (B, 3, H, W) float 0..1):
      train mode -> (level maps as YoloDetector, coefficients (B, k, A),
                     prototypes (B, k, H/s, W/s), s = config.proto_stride, 4, 2 or 1);
      eval mode  -> (predictions (B, A, 4 + nc + k): boxes xyxy [input px],
                     class probabilities, mask coefficients; prototypes);
                     proto_stride 1: a third output, see :meth:`_forward_detail`.
    """

    def __init__(self, num_classes: int = 3, num_prototypes: int = 16, width_multiple: float = 0.125,
                 depth_multiple: float = 0.33, config: Optional[ModelConfig] = None, **config_overrides: Any):
        if config is None:
            names = config_overrides.pop("class_names", None)
            if names is None:
                names = ModelConfig().class_names if num_classes == 3 else tuple(
                    f"class{i}" for i in range(num_classes))
            config = ModelConfig.scene_segmenter(num_classes=num_classes, class_names=names,
                                                 num_prototypes=num_prototypes, width_multiple=width_multiple,
                                                 depth_multiple=depth_multiple, **config_overrides)
        if config.task != "seg":
            raise ValueError(f"YoloSegmenter needs a config with task 'seg', got {config.task!r}")
        super().__init__(config)
        self.head = SegmentHead(config.num_classes, self.neck.out_channels, config.num_prototypes,
                                config.proto_channels, config.reg_max, self.strides, config.proto_stride,
                                config.detail_channels)

    def raw(self, images: torch.Tensor):
        """Train-style output in any mode (validation loss with eval-mode BatchNorm)."""
        return self.head(self.features(images), images)

    def forward(self, images: torch.Tensor):
        if not self.training and self.config.proto_stride == 1:
            return self._forward_detail(images)
        maps, coeffs, protos = self.raw(images)
        if self.training:
            return maps, coeffs, protos
        det = self.head.detect.decode(maps)
        return torch.cat((det, coeffs.transpose(1, 2)), dim=-1), protos

    def _forward_detail(self, images: torch.Tensor):
        """Eval mode, proto_stride 1: the full-resolution prototypes are never built.

        Returns (predictions (B, A, 4 + nc + k + d + 1): boxes, class
        probabilities, mask coefficients c, detail coefficients W^T c and
        b . c; coarse prototypes (B, k, H/2, W/2); detail features
        (B, d, H, W)), d = config.detail_channels. ``postprocess`` combines
        them per kept instance: logit = up(c . coarse) + (W^T c) . detail + b . c,
        which equals c . prototypes of train mode (see heads.Proto).
        """
        maps, coeffs, coarse, detail = self.head.forward_detail(self.features(images), images)
        det = self.head.detect.decode(maps)
        extra = self.head.proto.detail_coefficients(coeffs)
        return torch.cat((det, coeffs.transpose(1, 2), extra.transpose(1, 2)), dim=-1), coarse, detail


YoloModel = Union[YoloDetector, YoloSegmenter]


def build_model(config: ModelConfig) -> YoloModel:
    """The network a config describes (randomly initialised)."""
    if config.task == "seg":
        return YoloSegmenter(config=config)
    return YoloDetector(config=config)


def count_parameters(model: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)


# Inference settings a checkpoint may carry (calibrated for its weights; see check_inference_settings).
INFERENCE_KEYS = ("mask_threshold",)


def check_inference_settings(settings: Any, where: str = "inference settings") -> Dict[str, float]:
    """Validate a checkpoint's ``inference`` dict and return it as {key: float}.

    mask_threshold: probability above which a mask pixel is inside, in (0, 1); calibrated on a
    validation split by ``scripts/calibrate_mask_threshold`` (absent: PostprocessConfig's 0.5).
    Raises ValueError naming the bad key or value.
    """
    if not isinstance(settings, dict):
        raise ValueError(f"{where} must be a dict, got {type(settings).__name__}")
    out: Dict[str, float] = {}
    for key, value in settings.items():
        if key not in INFERENCE_KEYS:
            raise ValueError(f"{where}: unknown key {key!r} (known: {', '.join(INFERENCE_KEYS)})")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 < value < 1.0:
            raise ValueError(f"{where}: {key} must be a number in (0, 1), got {value!r}")
        out[key] = float(value)
    return out


def _write_checkpoint(path: str, ckpt: Dict[str, Any]) -> None:
    """torch.save to ``path + '.tmp'``, then rename: a crash never leaves a half-written file."""
    d = os.path.dirname(os.path.abspath(path))
    os.makedirs(d, exist_ok=True)
    tmp = path + ".tmp"
    torch.save(ckpt, tmp)
    os.replace(tmp, path)


def save_checkpoint(path: str, model: YoloModel, train_meta: Optional[Dict[str, Any]] = None,
                    optimizer_state: Optional[Dict[str, Any]] = None,
                    inference: Optional[Dict[str, float]] = None) -> None:
    """Write a weights_only-safe checkpoint (state_dict + config dict + metadata).

    train_meta: plain dict (str / int / float / list / dict values) such as
    {'epochs': 30, 'data': '/path', 'seed': 0, 'metrics': {...}};
    inference: calibrated inference settings (see :func:`check_inference_settings`).
    The file is written to ``path + '.tmp'`` then renamed, so a crash never
    leaves a half-written checkpoint.
    """
    ckpt = {
        "format": CHECKPOINT_FORMAT,
        "format_version": CHECKPOINT_VERSION,
        "model_config": model.config.to_dict(),
        "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "train": dict(train_meta or {}),
    }
    if inference:
        ckpt["inference"] = check_inference_settings(inference)
    if optimizer_state is not None:
        ckpt["optimizer"] = optimizer_state
    _write_checkpoint(path, ckpt)


def set_inference_settings(path: str, settings: Dict[str, float], out_path: Optional[str] = None) -> None:
    """Store calibrated inference settings in the checkpoint ``path`` (merged into any it holds),
    written to ``out_path`` (default: in place, atomically); weights and metadata are kept as they are."""
    ckpt = load_checkpoint(path)
    merged = dict(ckpt.get("inference") or {})
    merged.update(check_inference_settings(settings))
    ckpt["inference"] = merged
    _write_checkpoint(out_path or path, ckpt)


def average_checkpoints(paths: Sequence[str], out_path: str) -> Dict[str, Any]:
    """Write the uniform average of several checkpoints' weights to ``out_path`` (a "weight soup").

    Meant for runs of one recipe that differ only in their seed, fine-tuned from the
    same start: their weights lie in one basin, and the average is one network of the
    same size and speed. Floating-point tensors (weights and BatchNorm statistics) are
    averaged in float64 and stored in their own dtype; integer tensors (BatchNorm's
    update counters) are taken from the first checkpoint. The result keeps the first
    checkpoint's model_config and inference settings (recalibrate a segmenter's mask
    threshold for the average), and its "train" metadata records
    the files averaged (``averaged_from``) and each one's own metadata (``members``).
    Returns the metadata written. Raises ValueError for fewer than two paths, for
    checkpoints whose model_config (input size included) or tensor names / shapes
    differ, and for a checkpoint holding non-finite weights; FileNotFoundError for a
    missing file.
    """
    paths = list(paths)
    if len(paths) < 2:
        raise ValueError(f"average_checkpoints needs at least two checkpoints, got {len(paths)}")
    ckpts = [load_checkpoint(p) for p in paths]
    first = ckpts[0]
    for path, ck in zip(paths[1:], ckpts[1:]):
        if ck["model_config"] != first["model_config"]:
            raise ValueError(f"{path}: its model_config differs from {paths[0]}'s; only checkpoints of one "
                             f"network (same task, width, classes and input size) can be averaged")
        if set(ck["state_dict"]) != set(first["state_dict"]):
            raise ValueError(f"{path}: its tensor names differ from {paths[0]}'s")
    averaged: Dict[str, torch.Tensor] = {}
    for name, ref in first["state_dict"].items():
        tensors = [ck["state_dict"][name] for ck in ckpts]
        for path, t in zip(paths, tensors):
            if t.shape != ref.shape:
                raise ValueError(f"{path}: tensor {name} has shape {tuple(t.shape)}, "
                                 f"{paths[0]} has {tuple(ref.shape)}")
            if t.is_floating_point() and not torch.isfinite(t).all():
                raise ValueError(f"{path}: tensor {name} holds non-finite values")
        if ref.is_floating_point():
            averaged[name] = (sum(t.double() for t in tensors) / len(tensors)).to(ref.dtype)
        else:
            averaged[name] = ref.clone()
    meta = {"averaged_from": [os.path.abspath(p) for p in paths],
            "members": [dict(ck.get("train") or {}) for ck in ckpts]}
    out = dict(first, state_dict=averaged, train=meta)   # format, model_config, inference as the first file's
    out.pop("optimizer", None)                           # a last.pt's optimizer state does not fit the average
    _write_checkpoint(out_path, out)
    return meta


def load_checkpoint(path: str) -> Dict[str, Any]:
    """Read and check a checkpoint dict (weights_only=True).

    Raises FileNotFoundError if ``path`` does not exist and ValueError if it is
    not a CottonSim YOLO checkpoint (unreadable, wrong format or version).
    """
    if not isinstance(path, (str, os.PathLike)) or not os.path.isfile(path):
        raise FileNotFoundError(f"weights file not found: {path!r}")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for corrupt / foreign files
        raise ValueError(f"{path}: not a readable torch checkpoint ({type(exc).__name__}: {exc})") from exc
    if not isinstance(ckpt, dict) or ckpt.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{path}: not a CottonSim YOLO checkpoint (missing format '{CHECKPOINT_FORMAT}')")
    if ckpt.get("format_version") != CHECKPOINT_VERSION:
        raise ValueError(f"{path}: checkpoint format_version {ckpt.get('format_version')!r} "
                         f"is not supported (expected {CHECKPOINT_VERSION})")
    for key in ("model_config", "state_dict"):
        if not isinstance(ckpt.get(key), dict):
            raise ValueError(f"{path}: checkpoint has no '{key}' dict")
    return ckpt


def load_model(path: str, device: Union[str, torch.device] = "cpu") -> YoloModel:
    """Build the network stored in a checkpoint, load its weights, put it in eval mode.

    The returned model has ``.config`` (ModelConfig), ``.train_meta`` (dict) and
    ``.inference`` (calibrated inference settings, see :func:`check_inference_settings`).
    Raises FileNotFoundError / ValueError (see :func:`load_checkpoint`), and
    ValueError if the weights do not fit the stored configuration.
    """
    ckpt = load_checkpoint(path)
    try:
        config = ModelConfig.from_dict(ckpt["model_config"])
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: bad model_config: {exc}") from exc
    model = build_model(config)
    try:
        model.load_state_dict(ckpt["state_dict"], strict=True)
    except RuntimeError as exc:
        raise ValueError(f"{path}: weights do not match the stored model_config: {exc}") from exc
    model.train_meta = dict(ckpt.get("train", {}))
    model.inference = check_inference_settings(ckpt.get("inference") or {}, f"{path}: inference settings")
    return model.to(device).eval()
