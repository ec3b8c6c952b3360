"""Choosing a segmenter's mask threshold on a validation split.

Why: a mask pixel is inside when its probability exceeds the mask threshold
(0.5 unless calibrated). A network whose prototypes are coarser than the
thinnest structures it must draw (the stride-2 segmenter and the 2-3 px stems
of defoliated plants) gives those pixels probabilities below 0.5, so its
masks come out too thin and miss IoU 0.5; a lower threshold for *these
weights* fixes part of that without retraining. The threshold is chosen on a
validation split (never on the evaluation sets) and stored in the checkpoint
(``nn.models.set_inference_settings``), so every user of the weights gets it.

:func:`choose_mask_threshold` is the rule: the highest mask mAP50 ('all'
row), then the highest mask mAP50-95, then the threshold closest to 0.5 (a tie
keeps the uncalibrated behaviour where the data cannot tell).
"""
from __future__ import annotations

import math
from typing import Mapping, Tuple

NEUTRAL_MASK_THRESHOLD = 0.5


def choose_mask_threshold(scores: Mapping[float, Tuple[float, float]], tolerance: float = 1e-9) -> float:
    """The threshold with the best (mask mAP50, mask mAP50-95), ties -> closest to 0.5.

    scores: threshold (0..1, exclusive) -> (mAP50, mAP50-95) of the 'all' row on the validation split.
    Values within ``tolerance`` count as equal. Raises ValueError for no scores, a threshold
    outside (0, 1) or a non-finite score.
    """
    if not scores:
        raise ValueError("choose_mask_threshold needs at least one (threshold -> scores) entry")
    for t, pair in scores.items():
        if not 0.0 < float(t) < 1.0:
            raise ValueError(f"mask threshold must lie in (0, 1), got {t!r}")
        if len(pair) != 2 or not all(math.isfinite(float(v)) for v in pair):
            raise ValueError(f"scores for threshold {t} must be two finite numbers (mAP50, mAP50-95), got {pair!r}")
    best50 = max(float(p[0]) for p in scores.values())
    tied = {t: p for t, p in scores.items() if float(p[0]) >= best50 - tolerance}
    best5095 = max(float(p[1]) for p in tied.values())
    tied = [t for t, p in tied.items() if float(p[1]) >= best5095 - tolerance]
    return float(min(tied, key=lambda t: (abs(float(t) - NEUTRAL_MASK_THRESHOLD), float(t))))
