"""evaluation.mask_errors: missed and false pixels of a class mask, counted by hand."""
import numpy as np
import pytest

from cottonsim_perception.evaluation.mask_errors import MaskErrors, mask_errors


def test_counts_of_a_too_fat_and_shifted_mask():
    label = np.zeros((10, 10), bool)
    label[2:6, 2:6] = True                         # 16 px
    pred = np.zeros((10, 10), bool)
    pred[3:8, 3:6] = True                          # 15 px: 9 inside the label, 6 below it
    ground = np.zeros((10, 10), bool)
    ground[6:, :] = True
    sky = np.zeros((10, 10), bool)
    sky[:2, :] = True
    e = mask_errors(pred, label, {"ground": ground, "sky": sky})
    assert (e.labelled_px, e.missed_px, e.false_px) == (16, 7, 6)
    assert e.false_px_on == {"ground": 6, "sky": 0}
    assert e.iou == pytest.approx(9 / 22)
    assert "missed 0.438" in e.summary() and "on ground 0.375" in e.summary()


def test_sums_over_frames_and_edge_cases():
    a = MaskErrors(10, 2, 3, {"ground": 3})
    b = MaskErrors(5, 5, 1, {"ground": 0, "sky": 1})
    s = a + b
    assert (s.labelled_px, s.missed_px, s.false_px, s.false_px_on) == (15, 7, 4, {"ground": 3, "sky": 1})
    assert s.iou == pytest.approx(8 / 19)
    assert np.isnan(MaskErrors().iou) and MaskErrors().summary() == "no labelled pixels"
    empty = mask_errors(np.zeros((4, 4), bool), np.ones((4, 4), bool))
    assert (empty.missed_px, empty.false_px, empty.iou) == (16, 0, 0.0)
    with pytest.raises(ValueError, match="same"):
        mask_errors(np.zeros((4, 4), bool), np.zeros((4, 5), bool))
    with pytest.raises(ValueError, match="'sky'"):
        mask_errors(np.zeros((4, 4), bool), np.zeros((4, 4), bool), {"sky": np.zeros((3, 4), bool)})
