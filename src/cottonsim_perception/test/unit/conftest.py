"""Fixtures shared by the perception unit tests."""
import os
import pathlib

import cv2
import numpy as np
import pytest
import torch

from cottonsim_common.testing import load_script

SCRIPTS = pathlib.Path(__file__).resolve().parents[2] / "scripts"
TINY_W, TINY_H = 128, 96


@pytest.fixture
def perception_script():
    """load(name) -> the executable scripts/<name> as a module (its file has no .py suffix)."""

    return lambda name: load_script(SCRIPTS / name)


def _save_untrained(path, preset_name):
    """An untrained network of the named ModelConfig preset (width 1/16, 128x96 input) saved at ``path``."""
    from cottonsim_perception.nn.models import ModelConfig, build_model, save_checkpoint

    torch.manual_seed(0)
    cfg = getattr(ModelConfig, preset_name)(width_multiple=0.0625, input_width=TINY_W, input_height=TINY_H)
    save_checkpoint(path, build_model(cfg).eval(), {"epochs": 0})
    return path


def _save_small_random_network(path, kind):
    """A small untrained network (width 1/16, 160x128 input) with non-trivial BatchNorm statistics and class
    probabilities spread over 0..1 (so that folding and thresholds are exercised), saved at ``path``.
    kind: 'seg' (prototypes at stride 4), 'seg_stride1' (with its detail path switched on) or 'det'."""
    from cottonsim_perception.nn.models import ModelConfig, build_model, save_checkpoint

    torch.manual_seed(0)
    small = dict(width_multiple=0.0625, input_width=160, input_height=128)
    if kind == "det":
        cfg = ModelConfig.boll_detector(**small)
    else:
        cfg = ModelConfig.scene_segmenter(proto_stride=1 if kind == "seg_stride1" else 4, **small)
    model = build_model(cfg)
    g = torch.Generator().manual_seed(1)
    for m in model.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            n = m.num_features
            m.running_mean.copy_(torch.randn(n, generator=g) * 0.2)
            m.running_var.copy_(torch.rand(n, generator=g) + 0.5)
            m.weight.data.copy_(torch.rand(n, generator=g) + 0.5)
            m.bias.data.copy_(torch.randn(n, generator=g) * 0.1)
    head = model.head.detect if hasattr(model.head, "detect") else model.head
    for cls in head.cls:            # class probabilities spread over 0..1 (prior ~0.01)
        torch.nn.init.zeros_(cls[-1].bias)
    if cfg.proto_stride == 1:        # the detail path starts at zero: make it count
        torch.nn.init.normal_(model.head.proto.detail_out.weight, std=0.5)
        torch.nn.init.normal_(model.head.proto.detail_out.bias, std=0.5)
    save_checkpoint(path, model.eval())
    return path


@pytest.fixture(scope="session")
def save_small_random_network():
    """save(path, kind) -> path: see _save_small_random_network."""
    return _save_small_random_network


@pytest.fixture
def tiny_seg_weights(tmp_path):
    """An untrained scene segmenter (width 1/16, 128x96 input) saved as a checkpoint."""
    return _save_untrained(str(tmp_path / "seg.pt"), "scene_segmenter")


@pytest.fixture
def tiny_det_weights(tmp_path):
    """An untrained boll detector (width 1/16, 128x96 input) saved as a checkpoint."""
    return _save_untrained(str(tmp_path / "det.pt"), "boll_detector")


@pytest.fixture
def self_labelled_seg_data(tmp_path, tiny_seg_weights):
    """A 'valid' split of two noisy frames labelled with tiny_seg_weights' own best mask per class at
    mask threshold 0.5 (its largest outline), so that its scores depend on the mask threshold."""
    from cottonsim_perception.data import yolo_format as yf
    from cottonsim_perception.inference import Predictor

    root = str(tmp_path / "self_labelled")
    rng = np.random.default_rng(3)
    p = Predictor(tiny_seg_weights, conf_threshold=0.001, mask_threshold=0.5, threads=1)
    os.makedirs(os.path.join(root, "valid", "images"))
    for i in range(2):
        img = rng.integers(0, 255, (TINY_H, TINY_W, 3), dtype=np.uint8)
        cv2.imwrite(os.path.join(root, "valid", "images", f"{i}.png"), img[:, :, ::-1])
        det, insts = p.predict(img), []
        for c in range(3):
            of_class = np.flatnonzero(det.classes == c)
            if not len(of_class):
                continue
            mask = det.masks[of_class[np.argmax(det.scores[of_class])]].astype(np.uint8)
            contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
            outline = max(contours, key=cv2.contourArea).reshape(-1, 2).astype(float)
            if len(outline) < 3:
                continue
            poly = outline / [TINY_W, TINY_H]
            lo, hi = poly.min(0), poly.max(0)
            insts.append(yf.LabelInstance(c, np.r_[(lo + hi) / 2, hi - lo], poly))
        assert insts, "the untrained network gave no mask to label with"
        yf.write_label_file(os.path.join(root, "valid", "labels", f"{i}.txt"), insts, "seg")
    with open(os.path.join(root, "data.yaml"), "w") as fh:
        fh.write("train: valid/images\nval: valid/images\nnames: ['cotton plants', 'ground', 'sky']\n")
    return root
