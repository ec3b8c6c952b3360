"""Export a Cotton-Eye checkpoint to ONNX for the ``onnxruntime`` backend (``nn.backends``).

The ``.onnx`` file lies beside its checkpoint (:func:`onnx_path_for`: the same
name, suffix ``.onnx``) and is committed with it. It holds the fused
(BatchNorm folded) eval-mode network with a dynamic batch axis, input
``images`` (B, 3, H, W) float 0..1, and in its metadata the SHA-256 of the
checkpoint it was made from, so that a checkpoint retrained without a new
export is refused (:func:`check_export_matches`) instead of silently running
the old network. Pre- and post-processing are not part of the graph.
"""
from __future__ import annotations

import hashlib
import os
import warnings
from typing import Dict, Mapping, Optional

import torch

from .blocks import fuse_model
from .models import load_model

SOURCE_SHA_KEY = "cottonsim_source_sha256"
OPSET = 17


def onnx_path_for(weights_path: str) -> str:
    """The ONNX file that belongs to a checkpoint: ``dir/name.pt`` -> ``dir/name.onnx``."""
    return os.path.splitext(weights_path)[0] + ".onnx"


def file_sha256(path: str) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def output_names(task: str, outputs: int) -> list:
    """Names of the graph outputs: the detector's predictions; the segmenter's predictions,
    prototypes [, detail]."""
    names = ["predictions", "prototypes", "detail"] if task == "seg" else ["predictions"]
    return names[:outputs]


def export_onnx(weights_path: str, onnx_path: Optional[str] = None) -> Dict[str, object]:
    """Write the ONNX export of ``weights_path`` (default :func:`onnx_path_for`); returns what was written.

    Raises FileNotFoundError / ValueError (from ``load_model``) for a missing or invalid checkpoint.
    """
    onnx_path = onnx_path or onnx_path_for(weights_path)
    model = fuse_model(load_model(weights_path, "cpu"))
    cfg = model.config
    example = torch.zeros(1, 3, cfg.input_height, cfg.input_width)
    with torch.inference_mode():
        out = model(example)
    n_out = len(out) if isinstance(out, (tuple, list)) else 1
    names = output_names(cfg.task, n_out)
    with warnings.catch_warnings():
        # the shape checks in forward() become constants of the graph: the input size is fixed
        warnings.simplefilter("ignore")
        torch.onnx.export(model, (example,), onnx_path, dynamo=False, opset_version=OPSET,
                          input_names=["images"], output_names=names,
                          dynamic_axes={n: {0: "batch"} for n in ["images", *names]})
    _write_metadata(onnx_path, {SOURCE_SHA_KEY: file_sha256(weights_path), "task": cfg.task,
                                "input_width": str(cfg.input_width), "input_height": str(cfg.input_height)})
    return {"onnx": onnx_path, "task": cfg.task, "outputs": names, "bytes": os.path.getsize(onnx_path)}


def _write_metadata(onnx_path: str, values: Mapping[str, str]) -> None:
    import onnx

    model = onnx.load(onnx_path)
    del model.metadata_props[:]
    for key, value in sorted(values.items()):
        entry = model.metadata_props.add()
        entry.key, entry.value = key, str(value)
    onnx.save(model, onnx_path)


def check_export_matches(metadata: Mapping[str, str], weights_path: str, onnx_path: str) -> None:
    """ValueError unless ONNX ``metadata`` names ``weights_path``'s SHA-256 (the export is of these weights)."""
    want = metadata.get(SOURCE_SHA_KEY)
    if want is None:
        raise ValueError(f"'{onnx_path}' has no {SOURCE_SHA_KEY} metadata: not made by scripts/export_onnx")
    if want != file_sha256(weights_path):
        raise ValueError(f"'{onnx_path}' was exported from other weights than '{weights_path}' "
                         f"(re-run scripts/export_onnx {weights_path})")
