"""Predictor and class_masks: contract of the output types and input checks."""
import numpy as np
import pytest
import torch

from cottonsim_perception.inference import Predictor, class_masks
from cottonsim_perception.nn.models import ModelConfig, build_model, save_checkpoint
from cottonsim_perception.types import Detections, GroundTruth


@pytest.fixture(scope="module")
def seg_weights(tmp_path_factory):
    torch.manual_seed(0)
    cfg = ModelConfig.scene_segmenter(width_multiple=0.0625, input_width=128, input_height=96)
    path = str(tmp_path_factory.mktemp("w") / "seg.pt")
    save_checkpoint(path, build_model(cfg).eval(), {"epochs": 0})
    return path


def test_predict_returns_detections_in_original_pixels(seg_weights):
    p = Predictor(seg_weights, conf_threshold=0.0, iou_threshold=0.7, threads=1)
    img = np.random.default_rng(0).integers(0, 255, (120, 200, 3), dtype=np.uint8)
    det = p.predict(img)
    assert isinstance(det, Detections) and len(det) > 0      # threshold 0 keeps something
    assert det.masks.shape == (len(det), 120, 200) and det.masks.dtype == bool
    assert det.boxes_xyxy.dtype == np.float32 and det.classes.dtype == np.int64
    assert np.all(det.boxes_xyxy[:, [0, 2]] <= 200) and np.all(det.boxes_xyxy[:, [1, 3]] <= 120)
    assert np.all(np.diff(det.scores) <= 1e-6)               # sorted by score


def test_predict_rejects_bad_images(seg_weights):
    p = Predictor(seg_weights)
    with pytest.raises(ValueError, match="uint8"):
        p.predict(np.zeros((10, 10, 3), np.float32))
    with pytest.raises(ValueError, match="H, W, 3"):
        p.predict(np.zeros((10, 10), np.uint8))
    with pytest.raises(ValueError, match="empty"):
        p.predict(np.zeros((0, 10, 3), np.uint8))
    with pytest.raises(ValueError, match="numpy"):
        p.predict([[1, 2, 3]])


def test_predictor_missing_weights():
    with pytest.raises(FileNotFoundError):
        Predictor("/nonexistent/weights.pt")


def test_class_masks_is_the_union_per_class():
    m = np.zeros((3, 4, 5), bool)
    m[0, 0, 0] = m[1, 1, 1] = m[2, 2, 2] = True
    det = Detections(np.zeros((3, 4), np.float32), np.array([0.9, 0.8, 0.7], np.float32),
                     np.array([1, 2, 1], np.int64), m)
    cm = class_masks(det, (4, 5), num_classes=3)
    assert set(cm) == {0, 1, 2}
    assert not cm[0].any()
    assert cm[1].sum() == 2 and cm[1][0, 0] and cm[1][2, 2]
    assert cm[2].sum() == 1 and cm[2][1, 1]
    with pytest.raises(ValueError, match="masks is None"):
        class_masks(Detections(np.zeros((0, 4), np.float32), np.zeros(0, np.float32),
                               np.zeros(0, np.int64)), (4, 5))


def test_types_validate_their_arrays():
    with pytest.raises(ValueError, match="boxes_xyxy"):
        Detections(np.zeros((2, 3), np.float32), np.zeros(2, np.float32), np.zeros(2, np.int64))
    with pytest.raises(ValueError, match="classes"):
        GroundTruth(np.zeros((2, 4)), np.zeros(2, np.int32))
    with pytest.raises(ValueError, match="masks"):
        GroundTruth(np.zeros((1, 4)), np.zeros(1, np.int64), np.zeros((2, 4, 4), bool))
    assert len(Detections.empty((4, 5))) == 0
