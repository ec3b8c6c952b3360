"""Predictor and class_masks: contract of the output types and input checks."""
import numpy as np
import pytest
import torch

from cottonsim_perception.inference import Predictor, class_masks
from cottonsim_perception.evaluation.calibration import choose_mask_threshold
from cottonsim_perception.nn.models import load_checkpoint, load_model, save_checkpoint, set_inference_settings
from cottonsim_perception.types import Detections, GroundTruth


def test_predict_returns_detections_in_original_pixels(tiny_seg_weights):
    p = Predictor(tiny_seg_weights, conf_threshold=0.0, iou_threshold=0.7, threads=1)
    img = np.random.default_rng(0).integers(0, 255, (120, 200, 3), dtype=np.uint8)
    det = p.predict(img)
    assert isinstance(det, Detections) and len(det) > 0      # threshold 0 keeps something
    assert det.masks.shape == (len(det), 120, 200) and det.masks.dtype == bool
    assert det.boxes_xyxy.dtype == np.float32 and det.classes.dtype == np.int64
    assert np.all(det.boxes_xyxy[:, [0, 2]] <= 200) and np.all(det.boxes_xyxy[:, [1, 3]] <= 120)
    assert np.all(np.diff(det.scores) <= 1e-6)               # sorted by score


def test_predict_rejects_bad_images(tiny_seg_weights):
    p = Predictor(tiny_seg_weights)
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


def test_flip_tta_adds_the_mirrored_images_boxes_mirrored_back(tiny_det_weights):
    img = np.random.default_rng(1).integers(0, 255, (96, 128, 3), dtype=np.uint8)   # the input size
    plain = Predictor(tiny_det_weights, threads=1)
    tta = Predictor(tiny_det_weights, threads=1, flip_tta=True)
    own = plain.forward(img).predictions
    mirrored = plain.forward(np.ascontiguousarray(img[:, ::-1])).predictions
    both = tta.forward(img).predictions
    anchors = own.shape[1]
    assert both.shape == (1, 2 * anchors, own.shape[2])
    torch.testing.assert_close(both[:, :anchors], own, atol=1e-4, rtol=1e-4)
    second = both[:, anchors:]
    torch.testing.assert_close(second[..., 4:], mirrored[..., 4:], atol=1e-4, rtol=1e-4)     # scores
    torch.testing.assert_close(second[..., 0], 128.0 - mirrored[..., 2], atol=1e-3, rtol=1e-4)
    torch.testing.assert_close(second[..., 2], 128.0 - mirrored[..., 0], atol=1e-3, rtol=1e-4)
    torch.testing.assert_close(second[..., [1, 3]], mirrored[..., [1, 3]], atol=1e-3, rtol=1e-4)
    assert np.all(second[..., 2].numpy() >= second[..., 0].numpy())
    det = tta.predict(img)                       # one NMS over both halves, still in the frame
    assert np.all(det.boxes_xyxy[:, [0, 2]] <= 128 + 1e-3)


def test_flip_tta_is_refused_for_a_segmenter(tiny_seg_weights):
    with pytest.raises(ValueError, match="flip_tta is for detectors"):
        Predictor(tiny_seg_weights, flip_tta=True)


def test_calibrated_mask_threshold_travels_with_the_weights(tiny_seg_weights, tmp_path):
    assert Predictor(tiny_seg_weights).post_config.mask_threshold == 0.5          # nothing stored: the default
    calibrated = str(tmp_path / "calibrated.pt")
    set_inference_settings(tiny_seg_weights, {"mask_threshold": 0.4}, out_path=calibrated)
    assert load_model(calibrated).inference == {"mask_threshold": 0.4}
    assert load_model(tiny_seg_weights).inference == {}                           # the source is untouched
    p = Predictor(calibrated, conf_threshold=0.0)
    assert p.post_config.mask_threshold == 0.4
    assert Predictor(calibrated, mask_threshold=0.6).post_config.mask_threshold == 0.6   # explicit wins
    # a lower threshold can only grow each instance's mask (same network, same boxes)
    img = np.random.default_rng(1).integers(0, 255, (96, 128, 3), dtype=np.uint8)
    low, high = p.predict(img), Predictor(calibrated, conf_threshold=0.0, mask_threshold=0.6).predict(img)
    assert np.array_equal(low.boxes_xyxy, high.boxes_xyxy)
    assert np.all(low.masks | ~high.masks) and low.masks.sum() >= high.masks.sum()
    # weights and metadata are kept as they were
    a, b = load_checkpoint(tiny_seg_weights), load_checkpoint(calibrated)
    assert a["train"] == b["train"] and all(torch.equal(a["state_dict"][k], b["state_dict"][k]) for k in a["state_dict"])
    with pytest.raises(ValueError, match="mask_threshold"):
        set_inference_settings(calibrated, {"mask_threshold": 1.5})
    with pytest.raises(ValueError, match="unknown key 'nms'"):
        set_inference_settings(calibrated, {"nms": 0.5})
    with pytest.raises(ValueError, match="mask_threshold"):
        save_checkpoint(str(tmp_path / "bad.pt"), load_model(tiny_seg_weights), inference={"mask_threshold": 0.0})


def test_decoding_the_network_output_again_equals_predicting_with_that_threshold(tiny_seg_weights):
    """forward runs the network once; decode applies whatever post_config holds now."""
    import dataclasses

    p = Predictor(tiny_seg_weights, conf_threshold=0.0, threads=1)
    img = np.random.default_rng(2).integers(0, 255, (96, 128, 3), dtype=np.uint8)
    raw = p.forward(img)
    pixels = []
    for t in (0.3, 0.5, 0.7):
        p.post_config = dataclasses.replace(p.post_config, mask_threshold=t)
        a, b = p.decode(raw), p.predict(img)
        assert np.array_equal(a.boxes_xyxy, b.boxes_xyxy) and np.array_equal(a.masks, b.masks)
        pixels.append(int(a.masks.sum()))
    assert pixels[0] > pixels[1] > pixels[2]              # the threshold does act in decode
    with pytest.raises(ValueError, match="uint8"):
        p.forward(img.astype(np.float32))


def test_choose_mask_threshold_rule():
    # best mAP50 wins; among equal mAP50 the best mAP50-95; then the one closest to 0.5
    assert choose_mask_threshold({0.3: (0.85, 0.5), 0.4: (0.86, 0.4), 0.5: (0.80, 0.6)}) == 0.4
    assert choose_mask_threshold({0.3: (0.9, 0.5), 0.4: (0.9, 0.6), 0.5: (0.9, 0.55)}) == 0.4
    assert choose_mask_threshold({0.3: (0.9, 0.6), 0.4: (0.9, 0.6), 0.5: (0.9, 0.6), 0.6: (0.8, 0.6)}) == 0.5
    assert choose_mask_threshold({0.45: (0.9, 0.6), 0.55: (0.9, 0.6)}) == 0.45
    with pytest.raises(ValueError, match="at least one"):
        choose_mask_threshold({})
    with pytest.raises(ValueError, match=r"\(0, 1\)"):
        choose_mask_threshold({1.0: (0.9, 0.6)})
    with pytest.raises(ValueError, match="finite"):
        choose_mask_threshold({0.4: (float("nan"), 0.6)})


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
