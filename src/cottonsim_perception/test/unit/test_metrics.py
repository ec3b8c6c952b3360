"""Metrics against hand-computed cases (see the derivations in the comments)."""
import numpy as np
import pytest

from cottonsim_perception.evaluation.splits import evaluate_predictions
from cottonsim_perception.evaluation import metrics as M
from cottonsim_perception.types import Detections, GroundTruth


def det(boxes, scores, classes, masks=None):
    return Detections(np.asarray(boxes, np.float32).reshape(-1, 4), np.asarray(scores, np.float32),
                      np.asarray(classes, np.int64), masks)


def gt(boxes, classes, masks=None):
    return GroundTruth(np.asarray(boxes, np.float32).reshape(-1, 4), np.asarray(classes, np.int64), masks)


def row(result, name, kind="box"):
    return next(r for r in result[kind]["rows"] if r["class"] == name)


# ------------------------------------------------------------------ IoU

def test_box_iou_hand_values():
    a = [[0, 0, 2, 2], [0, 0, 10, 10]]
    b = [[1, 1, 3, 3], [20, 20, 30, 30], [0, 0, 10, 5]]
    iou = M.box_iou(a, b)
    # (0,0,2,2)-(1,1,3,3): 1 / (4 + 4 - 1); (0,0,2,2)-(0,0,10,5): 4 / 50;
    # (0,0,10,10)-(1,1,3,3): 4 / 100; (0,0,10,10)-(0,0,10,5): 50 / 100
    np.testing.assert_allclose(iou, [[1 / 7, 0, 4 / 50], [4 / 100, 0, 0.5]])
    assert M.box_iou(np.zeros((0, 4)), b).shape == (0, 3)
    with pytest.raises(ValueError, match="NaN"):
        M.box_iou([[0, 0, np.nan, 1]], b)


def test_mask_iou_of_known_masks():
    a = np.zeros((3, 8, 8), bool)
    a[0, 0:4, 0:4] = True            # 16 px
    a[1, 4:8, 4:8] = True            # 16 px, disjoint from b[0]
    b = np.zeros((2, 8, 8), bool)
    b[0, 0:4, 0:2] = True            # 8 px inside a[0]
    b[1, 0:4, 2:6] = True            # 16 px, overlaps a[0] by 8
    iou = M.mask_iou(a, b, chunk=2)  # chunking must not change anything
    np.testing.assert_allclose(iou, [[8 / 16, 8 / 24], [0, 0], [0, 0]])
    with pytest.raises(ValueError, match="sizes differ"):
        M.mask_iou(a, np.zeros((1, 4, 4), bool))


# ------------------------------------------------------------------ AP of known curves

def test_compute_ap_of_a_known_curve():
    recall = [0.2, 0.4, 0.4, 0.8]
    precision = [1.0, 1.0, 2 / 3, 0.8]
    # COCO: envelope 1 up to recall 0.4 (41 of the 101 points), 0.8 up to 0.8 (40), 0 after
    assert M.compute_ap(recall, precision, "coco") == pytest.approx((41 + 40 * 0.8) / 101)
    # Ultralytics: 1 on [0, 0.39], step to 0.8 over [0.39, 0.40], 0.8 on [0.4, 0.8],
    # then linear down to 0 at recall 1: 0.39 + 0.009 + 0.32 + 0.08
    assert M.compute_ap(recall, precision, "ultralytics") == pytest.approx(0.799)


def test_perfect_curve_is_0995_ultralytics_and_1_coco():
    assert M.compute_ap([0.5, 1.0], [1.0, 1.0], "ultralytics") == pytest.approx(0.995)
    assert M.compute_ap([0.5, 1.0], [1.0, 1.0], "coco") == pytest.approx(1.0)
    with pytest.raises(ValueError, match="method"):
        M.compute_ap([1.0], [1.0], "voc")


def test_ap_eq3_is_precision_at_true_positive_ranks():
    # r = 1, 0, 1: (1/1 + 2/3) / 2
    assert M.ap_eq3([True, False, True]) == pytest.approx((1 + 2 / 3) / 2)
    assert M.ap_eq3([False, False]) == 0.0


# ------------------------------------------------------------------ matching

def test_duplicate_detection_is_a_false_positive():
    iou = M.box_iou([[0, 0, 10, 10], [0, 0, 10, 8]], [[0, 0, 10, 10]])
    for method in ("score", "iou"):
        tp = M.match_predictions([0, 0], [0], iou, [0.5], scores=[0.9, 0.8], method=method)
        assert tp[:, 0].tolist() == [True, False]
    # by score, the higher-scored but worse box takes the ground truth
    tp = M.match_predictions([0, 0], [0], iou, [0.5], scores=[0.7, 0.8], method="score")
    assert tp[:, 0].tolist() == [False, True]
    tp = M.match_predictions([0, 0], [0], iou, [0.5], scores=[0.7, 0.8], method="iou")
    assert tp[:, 0].tolist() == [True, False]


def test_iou_threshold_edge_is_inclusive():
    iou = M.box_iou([[0, 0, 10, 5]], [[0, 0, 10, 10]])      # exactly 0.5
    tp = M.match_predictions([0], [0], iou, M.IOU_THRESHOLDS, scores=[0.9])
    assert tp[0].tolist() == [True] + [False] * 9
    r = evaluate_predictions([det([[0, 0, 10, 5]], [0.9], [0])], [gt([[0, 0, 10, 10]], [0])],
                             ["a"], "det")
    assert row(r, "a")["map50"] == pytest.approx(0.995)
    assert row(r, "a")["map50_95"] == pytest.approx(0.0995)


# ------------------------------------------------------------------ whole-dataset cases

def test_perfect_predictions():
    boxes1 = [[10, 10, 50, 40], [60, 5, 90, 30]]
    boxes2 = [[0, 0, 20, 20]]
    gts = [gt(boxes1, [0, 1]), gt(boxes2, [0])]
    dets = [det(boxes1, [0.9, 0.8], [0, 1]), det(boxes2, [0.7], [0])]
    r = evaluate_predictions(dets, gts, ["a", "b"], "det")
    for name in ("all", "a", "b"):
        x = row(r, name)
        assert x["p"] == pytest.approx(1.0) and x["r"] == pytest.approx(1.0)
        assert x["map50"] == pytest.approx(0.995) and x["map50_95"] == pytest.approx(0.995)
        assert x["fp"] == 0 and x["fn"] == 0
    assert row(r, "all")["instances"] == 3 and row(r, "a")["images"] == 2 and row(r, "b")["images"] == 1
    coco = evaluate_predictions(dets, gts, ["a", "b"], "det", ap_method="coco")
    assert row(coco, "all")["map50"] == pytest.approx(1.0)


def test_one_false_positive():
    # class a: 2 ground truths; predictions TP (0.9), FP (0.8), TP (0.7)
    g = gt([[0, 0, 10, 10], [50, 50, 60, 60]], [0, 0])
    d = det([[0, 0, 10, 10], [100, 100, 110, 110], [50, 50, 60, 60]], [0.9, 0.8, 0.7], [0, 0, 0])
    r = row(evaluate_predictions([d], [g], ["a"], "det"), "a")
    # recall .5, .5, 1; precision 1, .5, 2/3 -> envelope 1 to recall .5, 2/3 after:
    # 0.49 + (1 + 2/3)/2 * 0.01 + 2/3 * 0.49 + (2/3)/2 * 0.01
    assert r["map50"] == pytest.approx(0.49 + (5 / 3) / 200 + (2 / 3) * 0.49 + (2 / 3) / 200)
    # best F1 (0.8) is reached below confidence 0.7: P = 2/3, R = 1
    assert r["p"] == pytest.approx(2 / 3, abs=1e-6) and r["r"] == pytest.approx(1.0)
    assert (r["tp"], r["fp"], r["fn"]) == (2, 1, 0)
    assert r["ap50_eq3"] == pytest.approx((1 + 2 / 3) / 2)


def test_one_false_negative():
    g = gt([[0, 0, 10, 10], [50, 50, 60, 60]], [0, 0])
    d = det([[0, 0, 10, 10]], [0.9], [0])
    r = row(evaluate_predictions([d], [g], ["a"], "det"), "a")
    # envelope 1 up to recall .5, then linear to (1, 0): 0.5 + 0.25
    assert r["map50"] == pytest.approx(0.75)
    assert r["p"] == pytest.approx(1.0) and r["r"] == pytest.approx(0.5)
    assert (r["tp"], r["fp"], r["fn"]) == (1, 0, 1)
    assert r["ap50_eq3"] == pytest.approx(1.0)   # Eq. 3 ignores the missed object


def test_class_confusion_counts_as_miss_and_false_positive():
    g = gt([[0, 0, 10, 10]], [0])
    d = det([[0, 0, 10, 10]], [0.9], [1])
    r = evaluate_predictions([d], [g], ["a", "b"], "det")
    a, b, all_ = row(r, "a"), row(r, "b"), row(r, "all")
    assert a["map50"] == 0.0 and a["r"] == 0.0 and a["fn"] == 1
    assert b["instances"] == 0 and b["map50"] is None     # no ground truth: left out
    assert all_["map50"] == 0.0


def test_segmentation_uses_mask_iou_separately_from_box_iou():
    h, w = 20, 20
    gm = np.zeros((1, h, w), bool)
    gm[0, 0:10, 0:10] = True
    pm = np.zeros((1, h, w), bool)
    pm[0, 0:10, 0:4] = True                              # mask IoU 0.4, box IoU 1
    g = gt([[0, 0, 10, 10]], [0], gm)
    d = det([[0, 0, 10, 10]], [0.9], [0], pm)
    r = evaluate_predictions([d], [g], ["a"], "seg")
    assert row(r, "a", "box")["map50"] == pytest.approx(0.995)
    assert row(r, "a", "mask")["map50"] == 0.0
    with pytest.raises(ValueError, match="needs masks"):
        evaluate_predictions([det([[0, 0, 1, 1]], [0.9], [0])], [g], ["a"], "seg")


def test_bad_inputs_are_reported():
    g = gt([[0, 0, 10, 10]], [3])
    with pytest.raises(ValueError, match="outside 0..1"):
        evaluate_predictions([det([], [], [])], [g], ["a", "b"], "det")
    with pytest.raises(ValueError, match="predictions for"):
        evaluate_predictions([], [g], ["a"], "det")
    with pytest.raises(ValueError, match="method"):
        M.match_predictions([0], [0], [[1.0]], [0.5], method="best")


def test_no_predictions_gives_zero_not_nan():
    r = evaluate_predictions([det([], [], [])], [gt([[0, 0, 5, 5]], [0])], ["a"], "det")
    a = row(r, "a")
    assert a["map50"] == 0.0 and a["p"] == 0.0 and a["r"] == 0.0 and a["fn"] == 1
