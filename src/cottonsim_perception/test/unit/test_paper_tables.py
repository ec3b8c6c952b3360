"""The paper comparison rows built from an evaluate result."""
import numpy as np
import pytest

from cottonsim_perception.evaluation.splits import evaluate_predictions
from cottonsim_perception.evaluation.paper import comparison_rows
from cottonsim_perception.types import Detections, GroundTruth


def _result():
    # two images, one boll each: one found (IoU 1), one missed -> P 1.0, R 0.5
    box = np.array([[10, 10, 20, 20]], np.float32)
    dets = [Detections(box, np.array([0.9], np.float32), np.array([0], np.int64)),
            Detections(np.zeros((0, 4), np.float32), np.zeros(0, np.float32), np.zeros(0, np.int64))]
    gts = [GroundTruth(box, np.array([0], np.int64)), GroundTruth(box + 30, np.array([0], np.int64))]
    return evaluate_predictions(dets, gts, ["cotton boll"], "det")


def test_rows_carry_our_metrics_and_the_paper_test_figures():
    rows = comparison_rows(_result(), "table3", "demo")
    assert len(rows) == 2
    cells = [c.strip() for c in rows[1].strip("|").split("|")]
    assert cells[:4] == ["demo", "cotton boll", "2", "2"]
    assert float(cells[4]) == pytest.approx(100.0) and float(cells[5]) == pytest.approx(50.0)
    assert cells[8] == "94.8 / 87.2 / 92.7"
    assert comparison_rows(_result(), "", "x")[0].rstrip().endswith("| - |")


def test_bad_table_or_result_is_a_clear_error():
    with pytest.raises(ValueError, match="table must be"):
        comparison_rows(_result(), "table9")
    with pytest.raises(ValueError, match="'mask' metrics"):
        comparison_rows({"task": "seg", "box": {}}, "table3")
