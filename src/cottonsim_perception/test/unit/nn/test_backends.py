"""The ONNX Runtime backend runs the same network as torch: raw outputs within OUTPUT_TOLERANCE, the same
detections, one batched pass equal to frame-by-frame passes, and clear errors for missing or stale exports."""
import os
import pathlib
import shutil

import numpy as np
import pytest
import torch

from cottonsim_perception.inference import Predictor
from cottonsim_perception.nn.backends import OUTPUT_TOLERANCE, check_backend_name
from cottonsim_perception.nn.models import build_model, save_checkpoint
from cottonsim_perception.nn.onnx_export import export_onnx, onnx_path_for

SHIPPED = pathlib.Path(__file__).resolve().parents[3] / "weights"
SHIPPED_WEIGHTS = ["scene_segmenter.pt", "scene_segmenter_fine.pt", "boll_detector_sim.pt", "boll_detector.pt"]


def _frames(count, height=480, width=640, seed=0):
    """Frames with structure (smooth colour fields + noise), so networks give non-trivial outputs."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:height, 0:width] / max(height, width)
    frames = []
    for _ in range(count):
        base = np.stack([np.sin(xx * rng.uniform(2, 9) + rng.uniform(0, 6)) for _ in range(3)], axis=-1)
        img = 127 + 100 * base + rng.normal(0, 12, (height, width, 3))
        frames.append(np.clip(img, 0, 255).astype(np.uint8))
    return frames


@pytest.fixture(scope="module", params=["seg", "seg_stride1", "det"])
def exported(request, tmp_path_factory, save_small_random_network):
    """A small random network of each kind, its checkpoint and its ONNX export."""
    path = save_small_random_network(str(tmp_path_factory.mktemp("w") / f"{request.param}.pt"), request.param)
    export_onnx(path)
    return path


def _max_difference(weights, frames):
    a = Predictor(weights, backend="torch", threads=1, conf_threshold=0.01)
    b = Predictor(weights, backend="onnxruntime", threads=1, conf_threshold=0.01)
    outs_a, outs_b = a.forward_batch(frames), b.forward_batch(frames)
    diff = 0.0
    for oa, ob in zip(outs_a, outs_b):
        for ta, tb in zip((oa.predictions, oa.prototypes, oa.detail), (ob.predictions, ob.prototypes, ob.detail)):
            assert (ta is None) == (tb is None)
            if ta is not None:
                assert ta.shape == tb.shape
                diff = max(diff, float((ta - tb).abs().max()))
    return diff, a, b


def test_onnxruntime_outputs_equal_torch_on_small_networks(exported):
    diff, a, _ = _max_difference(exported, _frames(2))
    assert diff <= OUTPUT_TOLERANCE
    assert len(a.predict(_frames(1)[0])) > 0          # the outputs compared hold detections


@pytest.mark.parametrize("name", SHIPPED_WEIGHTS)
def test_shipped_exports_equal_torch(name):
    weights = str(SHIPPED / name)
    assert os.path.isfile(onnx_path_for(weights)), f"{onnx_path_for(weights)} is not committed"
    diff, _, _ = _max_difference(weights, _frames(2))
    assert diff <= OUTPUT_TOLERANCE


def test_one_batched_pass_equals_frame_by_frame(exported):
    p = Predictor(exported, backend="onnxruntime", threads=1, conf_threshold=0.01)
    frames = _frames(2, seed=2)
    batched = p.predict_batch(frames)
    for frame, together in zip(frames, batched):
        alone = p.predict(frame)
        np.testing.assert_allclose(alone.boxes_xyxy, together.boxes_xyxy, atol=1e-3)
        np.testing.assert_allclose(alone.scores, together.scores, atol=1e-5)


def test_torch_backend_batches_frame_by_frame(exported):
    p = Predictor(exported, backend="torch", threads=1, conf_threshold=0.01)
    frames = _frames(2, seed=3)
    for frame, together in zip(frames, p.predict_batch(frames)):
        np.testing.assert_allclose(p.predict(frame).boxes_xyxy, together.boxes_xyxy, atol=1e-4)


def test_missing_export_names_the_file_and_the_script(tmp_path, exported):
    lone = str(tmp_path / "lone.pt")
    shutil.copy(exported, lone)
    with pytest.raises(FileNotFoundError, match="export_onnx"):
        Predictor(lone, backend="onnxruntime")


def test_an_export_of_other_weights_is_refused(tmp_path, exported):
    other = str(tmp_path / "other.pt")
    torch.manual_seed(5)
    cfg = Predictor(exported).config
    save_checkpoint(other, build_model(cfg).eval())
    shutil.copy(onnx_path_for(exported), onnx_path_for(other))
    with pytest.raises(ValueError, match="other weights"):
        Predictor(other, backend="onnxruntime")


def test_an_unreadable_export_is_a_value_error(tmp_path, exported):
    broken = str(tmp_path / "broken.pt")
    shutil.copy(exported, broken)
    pathlib.Path(onnx_path_for(broken)).write_bytes(b"not an onnx file")
    with pytest.raises(ValueError, match="cannot load"):
        Predictor(broken, backend="onnxruntime")


def test_backend_names_are_checked(exported):
    assert check_backend_name("onnxruntime") == "onnxruntime"
    with pytest.raises(ValueError, match="backend must be one of"):
        Predictor(exported, backend="tensorrt")


def test_a_batch_of_the_wrong_size_is_refused(exported):
    p = Predictor(exported, backend="onnxruntime")
    with pytest.raises(ValueError, match="must be"):
        p.backend.run(np.zeros((1, 10, 10, 3), dtype=np.uint8))
    with pytest.raises(ValueError, match="at least one image"):
        p.forward_batch([])
