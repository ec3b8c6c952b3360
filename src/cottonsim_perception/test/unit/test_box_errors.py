"""evaluation.box_errors (hand-counted misses and false positives by kind, the AP's matching) and the
box_errors script (per manifest group, JSON, one-line errors)."""
import json
import os

import cv2
import numpy as np
import pytest

from cottonsim_perception.evaluation.box_errors import (BoxErrorConfig, BoxErrors, box_errors, format_box_errors,
                                                       format_misses_by_size, misses_by_size)
from cottonsim_perception.evaluation.metrics import box_iou, match_predictions
from cottonsim_perception.types import Detections

# labelled: A and B overlap each other, C stands alone, D reaches into the ignore box
GT = np.array([[0, 0, 10, 10], [9, 0, 19, 10], [50, 50, 60, 60], [200, 200, 210, 210]], float)
IGNORE = np.array([[205, 205, 230, 230]], float)
PRED = np.array([
    [0, 0, 10, 10],          # P1 finds A
    [12, 2, 18, 8],          # P2 inside B: IoU 0.36 -> B misplaced, P2 a false positive near a label
    [55, 55, 65, 65],        # P3 IoU 0.14 with C -> C weak, P3 a background false positive
    [300, 300, 310, 310],    # P4 background false positive
    [0, 0, 10, 11],          # P5 a duplicate of A (taken by P1): a false positive near a label
    [210, 210, 225, 225],    # P6 inside the ignore box: neither true nor false
], float)
SCORES = np.array([0.9, 0.8, 0.6, 0.5, 0.7, 0.4])


def test_hand_counted_misses_and_false_positives():
    e = box_errors(PRED, SCORES, np.zeros(6, int), GT, np.zeros(4, int), IGNORE)
    assert e == BoxErrors(labelled=4, touching=3, found=1, misplaced=1, weak=1, unseen=1,
                          misplaced_touching=1, weak_touching=0, unseen_touching=1,
                          false_positives=4, fp_near_label=2, fp_background=2, on_ignore=1)
    assert e.missed == 3 and e.as_dict()["missed"] == 3
    text = format_box_errors(e)
    assert "found 1 (25.0 %), missed 3" in text and "misplaced (a prediction at IoU 0.3-0.5) 1" in text


def test_misses_by_size_and_touching():
    table = misses_by_size(PRED, SCORES, np.zeros(6, int), GT, np.zeros(4, int), IGNORE, size_edges_px=(5, 20))
    assert table.shape == (3, 2, 2)
    # every labelled box is 10 px: bin 1; C stands alone and is missed, of A, B, D (touching) B and D are
    assert table[1].tolist() == [[1, 1], [3, 2]] and table[0].sum() == 0 and table[2].sum() == 0
    text = format_misses_by_size(table, (5, 20))
    assert "5-20: 100.0 % of    1 |  66.7 % of    3" in text and ">= 20" in text
    with pytest.raises(ValueError, match="size_edges_px"):
        misses_by_size(PRED, SCORES, np.zeros(6, int), GT, np.zeros(4, int), size_edges_px=(20, 5))
    with pytest.raises(ValueError, match="does not fit"):
        format_misses_by_size(table, (5,))


def test_found_boxes_are_the_aps_true_positives():
    rng = np.random.default_rng(0)
    for _ in range(20):
        gt = rng.uniform(0, 80, (6, 2)).repeat(2, axis=1)[:, [0, 2, 1, 3]] + [0, 0, 12, 12]
        pred = gt[rng.integers(0, 6, 8)] + rng.normal(0, 3, (8, 4))
        scores, pc, gc = rng.uniform(size=8), rng.integers(0, 2, 8), rng.integers(0, 2, 6)
        tp = match_predictions(pc, gc, box_iou(pred, gt), [0.5], scores=scores)[:, 0]
        e = box_errors(pred, scores, pc, gt, gc)
        assert e.found == int(tp.sum()) and e.found + e.missed == 6
        assert e.false_positives == 8 - int(tp.sum())          # no ignore boxes: every other prediction


def test_a_prediction_of_another_class_finds_nothing():
    e = box_errors(GT[:1], [0.9], [1], GT[:1], [0])
    assert (e.found, e.unseen, e.false_positives, e.fp_background) == (0, 1, 1, 1)


def test_counts_add_and_empty_inputs():
    none = box_errors(np.zeros((0, 4)), [], [], np.zeros((0, 4)), [])
    assert none == BoxErrors()
    only_labels = box_errors(np.zeros((0, 4)), [], [], GT, np.zeros(4, int), IGNORE)
    assert only_labels.unseen == 4 and only_labels.touching == 3
    total = only_labels + box_errors(PRED, SCORES, np.zeros(6, int), GT, np.zeros(4, int), IGNORE)
    assert total.labelled == 8 and total.unseen == 5 and total.found == 1


@pytest.mark.parametrize("kwargs, name", [({"match_iou": 0.0}, "match_iou"), ({"near_iou": 1.5}, "near_iou"),
                                          ({"weak_iou": 0.4}, "weak_iou <= near_iou")])
def test_bad_config_names_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        BoxErrorConfig(**kwargs)


def test_bad_boxes_raise_clear_errors():
    with pytest.raises(ValueError, match="pred_boxes"):
        box_errors(np.zeros((2, 3)), [0, 0], [0, 0], GT, np.zeros(4, int))
    with pytest.raises(ValueError, match="scores"):
        box_errors(PRED, SCORES[:2], np.zeros(6, int), GT, np.zeros(4, int))
    with pytest.raises(ValueError, match="NaN"):
        box_errors(PRED + np.nan, SCORES, np.zeros(6, int), GT, np.zeros(4, int))


class _FixedPredictor:
    """Stands in for Predictor: the same PRED boxes (scaled into the 128x96 frame) on every image."""
    task, class_names = "det", ["cotton boll"]

    def __init__(self, weights, conf_threshold=0.25, threads=None):
        self.conf = conf_threshold

    def predict(self, rgb):
        keep = SCORES >= self.conf
        return Detections((PRED[keep] / 2.5).astype(np.float32), SCORES[keep].astype(np.float32),
                          np.zeros(int(keep.sum()), np.int64))


def _write_dataset(root):
    from cottonsim_perception.data import yolo_format as yf
    os.makedirs(os.path.join(root, "test", "images"))
    rows = ["file,mode"]
    for i, mode in enumerate(("close", "side", "side")):
        cv2.imwrite(os.path.join(root, "test", "images", f"{i}.png"), np.zeros((96, 128, 3), np.uint8))
        boxes = GT[:3] / 2.5                                # A, B, C inside the frame
        insts = [yf.LabelInstance(0, np.array([(b[0] + b[2]) / 256, (b[1] + b[3]) / 192,
                                               (b[2] - b[0]) / 128, (b[3] - b[1]) / 96])) for b in boxes]
        yf.write_label_file(os.path.join(root, "test", "labels", f"{i}.txt"), insts, "det")
        rows.append(f"test/images/{i}.png,{mode}")
    with open(os.path.join(root, "manifest.csv"), "w") as fh:
        fh.write("\n".join(rows) + "\n")
    with open(os.path.join(root, "data.yaml"), "w") as fh:
        fh.write("train: test/images\nval: test/images\nnames: ['cotton boll']\n")


def test_script_reports_per_group_and_writes_json(tmp_path, perception_script, monkeypatch, capsys):
    script = perception_script("box_errors")
    monkeypatch.setattr(script, "Predictor", _FixedPredictor)
    data, out = str(tmp_path / "d"), str(tmp_path / "e.json")
    _write_dataset(data)
    assert script.main(["--weights", "w.pt", "--data", data, "--group-by", "mode", "--json", out]) == 0
    printed = capsys.readouterr().out
    assert "mode = close images (1)" in printed and "mode = side images (2)" in printed
    with open(out) as fh:
        reports = json.load(fh)["reports"]
    # per image: A found, B misplaced, C weak (D is not labelled here); P2-P6 false positives (no ignore boxes)
    assert reports["close"]["found"] == 1 and reports["side"]["misplaced"] == 2
    assert reports["all"]["labelled"] == 9 and reports["all"]["weak"] == 3 and reports["all"]["images"] == 3
    assert reports["all"]["false_positives"] == 15
    # 4 px boxes, all in the first bin: C alone (missed), A and B touching (B missed), in each of 3 images
    assert reports["all"]["by_size"]["labelled_missed_alone_touching"][0] == [[3, 3], [6, 3]]
    assert "misses by box size" in printed
    assert script.main(["--weights", "w.pt", "--data", data, "--conf", "0.65", "--json", out]) == 0
    with open(out) as fh:
        assert json.load(fh)["reports"]["all"]["false_positives"] == 6      # P2 and P5, per image


def test_script_errors_are_one_line_and_exit_2(tmp_path, perception_script, capsys, tiny_seg_weights):
    script = perception_script("box_errors")
    data = str(tmp_path / "d")
    _write_dataset(data)
    assert script.main(["--weights", tiny_seg_weights, "--data", data]) == 2
    assert "not a detector" in capsys.readouterr().err
    assert script.main(["--weights", str(tmp_path / "missing.pt"), "--data", data]) == 2
    assert "box_errors: error:" in capsys.readouterr().err
    assert script.main(["--weights", tiny_seg_weights, "--data", data, "--conf", "1.5"]) == 2
    assert "--conf" in capsys.readouterr().err
    assert script.main(["--weights", tiny_seg_weights, "--data", data, "--size-edges", "16,x"]) == 2
    assert "--size-edges" in capsys.readouterr().err
