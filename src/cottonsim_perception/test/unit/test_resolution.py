"""The coarse-resolution mask bound."""
import numpy as np
import pytest

from cottonsim_perception.evaluation.resolution import coarse_mask_iou, fraction_reachable


def test_blocks_are_exact_and_thin_lines_are_not():
    block = np.zeros((64, 64), bool)
    block[16:48, 8:40] = True                 # aligned to 8-px cells: exact at 1/8
    assert coarse_mask_iou(block, 8) > 0.95
    line = np.zeros((64, 64), bool)
    line[:, 30] = True                        # a 1-px stem: at 1/8 it smears over a cell
    assert coarse_mask_iou(line, 8) < 0.5
    assert coarse_mask_iou(line, 1) == pytest.approx(1.0)
    assert fraction_reachable([block, line, np.zeros((64, 64), bool)], 8) == pytest.approx(0.5)


def test_bad_input():
    with pytest.raises(ValueError, match="factor"):
        coarse_mask_iou(np.ones((4, 4), bool), 0)
    with pytest.raises(ValueError, match="no non-empty"):
        fraction_reachable([np.zeros((4, 4), bool)], 2)
