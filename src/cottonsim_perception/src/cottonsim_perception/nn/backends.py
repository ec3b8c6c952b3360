"""Inference backends: what runs a Cotton-Eye network's forward pass on letterboxed frames.

A backend takes a batch of letterboxed uint8 RGB frames (B, H, W, 3) at the
network's input size and returns the network's eval-mode outputs as float32
numpy arrays (the detector: predictions; the segmenter: predictions,
prototypes [, detail]). Pre-processing (letterbox) and post-processing (NMS,
masks) stay in :class:`cottonsim_perception.inference.Predictor`, the same
for every backend.

* ``onnxruntime`` (:class:`OnnxRuntimeBackend`): the network exported to
  ONNX beside its checkpoint (``<weights>.onnx``, ``scripts/export_onnx``,
  :mod:`.onnx_export`), run by ONNX Runtime's CPU execution provider.
  About 1.5-1.8x less CPU per frame than the torch backend
  (docs/benchmarks.md); batches of any size in one call.
* ``torch`` (:class:`TorchBackend`): the fused PyTorch model, frozen as a
  channels-last TorchScript graph at batch 1 (``optimize``, ``nn.optimize``)
  or eager; a batch runs frame by frame. Training and the checkpoints stay
  torch; this backend needs no export.

Outputs of the two agree within :data:`OUTPUT_TOLERANCE` (unit test
``test_backends``).
"""
from __future__ import annotations

import abc
import warnings
from typing import Optional, Tuple

import numpy as np
import torch

from .optimize import freeze_for_inference

BACKENDS = ("onnxruntime", "torch")
# Largest absolute difference allowed between the two backends' raw outputs on the shipped weights:
# boxes in input pixels (0..960), class probabilities and mask prototypes (O(1)). Measured: <= 3e-4 px.
OUTPUT_TOLERANCE = 5e-3
INPUT_NAME = "images"


def check_backend_name(name: str) -> str:
    """``name`` if it is one of :data:`BACKENDS`, else ValueError naming the choices."""
    if name not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {name!r}")
    return name


def check_batch(images: np.ndarray, height: int, width: int) -> None:
    """ValueError unless ``images`` is a (B >= 1, height, width, 3) uint8 array."""
    if not isinstance(images, np.ndarray) or images.dtype != np.uint8:
        raise ValueError(f"a backend batch must be a uint8 numpy array, got {getattr(images, 'dtype', type(images))}")
    if images.ndim != 4 or images.shape[0] < 1 or images.shape[1:] != (height, width, 3):
        raise ValueError(f"a backend batch must be (B, {height}, {width}, 3), got {images.shape}")


class InferenceBackend(abc.ABC):
    """The forward pass of one loaded network at a fixed input size (height x width px)."""

    name = ""

    def __init__(self, height: int, width: int):
        self.height = int(height)
        self.width = int(width)

    def run(self, images: np.ndarray) -> Tuple[np.ndarray, ...]:
        """Eval-mode outputs (float32, batch first) for (B, H, W, 3) uint8 letterboxed RGB frames."""
        check_batch(images, self.height, self.width)
        return self._run(images)

    @abc.abstractmethod
    def _run(self, images: np.ndarray) -> Tuple[np.ndarray, ...]:
        """``run`` after the batch was checked."""


class TorchBackend(InferenceBackend):
    """The fused torch model; frozen channels-last TorchScript when ``optimize`` (falls back to eager)."""

    name = "torch"

    def __init__(self, model: torch.nn.Module, height: int, width: int, optimize: bool = True):
        super().__init__(height, width)
        self.model = model
        self.network = model
        self.optimized = False
        if optimize:
            try:
                self.network = freeze_for_inference(model, self.height, self.width)
                self.optimized = True
            except (RuntimeError, AttributeError) as exc:   # a torch without TorchScript: stay eager
                warnings.warn(f"TorchBackend: frozen TorchScript unavailable ({exc}); running the eager model")

    def tensor(self, image: np.ndarray) -> torch.Tensor:
        """(1, 3, H, W) float 0..1 input of one (H, W, 3) uint8 frame in the layout the network wants."""
        device = next(self.model.parameters()).device
        # (H, W, 3) viewed as (1, 3, H, W) is already channels-last: no copy before the float cast
        x = torch.from_numpy(np.ascontiguousarray(image)).to(device).permute(2, 0, 1)[None]
        if not self.optimized:
            x = x.contiguous()      # the eager model keeps NCHW weights
        return x.float().div_(255.0)

    def _run(self, images: np.ndarray) -> Tuple[np.ndarray, ...]:
        per_frame = []
        with torch.inference_mode():
            for image in images:          # the frozen graph was traced at batch 1
                out = self.network(self.tensor(image))
                out = out if isinstance(out, (tuple, list)) else (out,)
                per_frame.append([o.float().cpu() for o in out])
        return tuple(torch.cat(parts, dim=0).numpy() for parts in zip(*per_frame))


class OnnxRuntimeBackend(InferenceBackend):
    """An exported ``.onnx`` file run by ONNX Runtime on the CPU.

    threads: intra-op threads (None: ONNX Runtime's default, one per core);
    spinning: let idle worker threads spin between operators (faster alone on
    a machine, wasted CPU when the cores are shared; off by default).
    Raises FileNotFoundError / ValueError for a missing or unloadable file.
    """

    name = "onnxruntime"

    def __init__(self, onnx_path: str, height: int, width: int, threads: Optional[int] = None,
                 spinning: bool = False):
        super().__init__(height, width)
        import onnxruntime as ort

        options = ort.SessionOptions()
        options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        options.inter_op_num_threads = 1
        if threads is not None:
            options.intra_op_num_threads = int(threads)
        options.add_session_config_entry("session.intra_op.allow_spinning", "1" if spinning else "0")
        options.log_severity_level = 3          # errors only: no notes about unused initialisers
        try:
            self.session = ort.InferenceSession(onnx_path, options, providers=["CPUExecutionProvider"])
        except Exception as exc:      # onnxruntime raises its own Fail / InvalidGraph / NoSuchFile types
            raise ValueError(f"ONNX Runtime cannot load '{onnx_path}': {exc}") from exc
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            raise ValueError(f"'{onnx_path}' must have one input, has {len(inputs)}")
        self.input_name = inputs[0].name
        shape = inputs[0].shape
        if len(shape) != 4 or shape[1:] != [3, self.height, self.width]:
            raise ValueError(f"'{onnx_path}' takes input {shape}, the checkpoint (B, 3, {self.height}, {self.width})")
        self.metadata = dict(self.session.get_modelmeta().custom_metadata_map)

    def _run(self, images: np.ndarray) -> Tuple[np.ndarray, ...]:
        x = np.ascontiguousarray(images.transpose(0, 3, 1, 2), dtype=np.float32)
        x /= np.float32(255.0)
        return tuple(self.session.run(None, {self.input_name: x}))
