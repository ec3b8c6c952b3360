"""Inference-only speed-ups of a loaded network that keep its outputs (up to float rounding).

The CPU-sized networks of this package are small (the scene segmenter has ~80
convolutions on feature maps of a few thousand values each), so per frame the
time goes as much into the Python/ATen dispatch of ~250 small operators as into
the arithmetic. Three exact transformations remove most of that:

* BatchNorm folded into the preceding convolution (``blocks.fuse_model``);
* channels-last (NHWC) memory format for weights and activations, which lets
  oneDNN/ATen pick their NHWC convolution kernels and avoids the layout
  reorders of NCHW inputs;
* a TorchScript trace of the fused model at the fixed input size, frozen
  (``torch.jit.freeze``: weights become constants, the graph runs without the
  Python module tree).

Outputs equal the eager model's up to float re-association inside the
convolution kernels (max abs difference ~1e-4 on logits / box pixels; the unit
test ``test_optimize`` bounds it).
"""
from __future__ import annotations

import warnings
from typing import Callable

import torch
import torch.nn as nn

from .blocks import fuse_model


def freeze_for_inference(model: nn.Module, height: int, width: int, channels_last: bool = True,
                         warmup_calls: int = 2) -> Callable[[torch.Tensor], object]:
    """A frozen TorchScript version of ``model`` for (1, 3, height, width) inputs.

    model: an eval-mode YOLO network (BatchNorm folded here if not yet);
    height / width: the network input [px] (traced at that size, batch 1);
    channels_last: store weights and expect inputs in NHWC memory format
    (inputs in NCHW still work, at the cost of one reorder); warmup_calls:
    calls made here so that the profiling executor's first, slower runs do
    not fall on the first camera frame.
    Returns a callable with the model's eval-mode outputs. The model itself
    is modified in place (fused, and NHWC when channels_last).
    Raises ValueError for a model in training mode or a bad input size.
    """
    if model.training:
        raise ValueError("freeze_for_inference needs an eval-mode model (call .eval() first)")
    if int(height) < 32 or int(width) < 32:
        raise ValueError(f"freeze_for_inference: input size must be >= 32 px, got {width}x{height}")
    fuse_model(model)
    device = next(model.parameters()).device
    example = torch.zeros(1, 3, int(height), int(width), device=device)
    if channels_last:
        model.to(memory_format=torch.channels_last)
        example = example.contiguous(memory_format=torch.channels_last)
    with torch.inference_mode(), warnings.catch_warnings():
        # the shape checks in forward() become constants of the trace: expected, input size is fixed
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        # torch 2.13 marks trace / freeze deprecated (in favour of torch.compile, which needs a C++
        # toolchain at run time); they still work, and Predictor falls back to eager if they fail
        warnings.simplefilter("ignore", DeprecationWarning)
        traced = torch.jit.trace(model, example, check_trace=False)
        frozen = torch.jit.freeze(traced.eval())
        for _ in range(max(0, int(warmup_calls))):
            frozen(example)
    return frozen
