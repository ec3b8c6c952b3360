"""Where a predicted class mask goes wrong, pixel by pixel.

Why: a mask IoU below 0.5 can come from a mask that misses labelled pixels
(too thin, parts not found) or from one that covers pixels of other classes
(too fat, gaps filled in). :class:`MaskErrors` counts both against one
labelled class mask, the false pixels split by the class labelled there, so
that a diagnosis says which of the two to work on. Counts add over frames.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Mapping

import numpy as np


@dataclass
class MaskErrors:
    """Pixel counts of one predicted mask (or a sum over frames) against its labelled mask.

    labelled_px: pixels of the label; missed_px: labelled pixels the
    prediction leaves out; false_px: predicted pixels outside the label;
    false_px_on: of those, the pixels labelled as each other class (by name);
    the rest of false_px lies on unlabelled pixels.
    """

    labelled_px: int = 0
    missed_px: int = 0
    false_px: int = 0
    false_px_on: Dict[str, int] = field(default_factory=dict)

    def __add__(self, other: "MaskErrors") -> "MaskErrors":
        on = dict(self.false_px_on)
        for name, n in other.false_px_on.items():
            on[name] = on.get(name, 0) + n
        return MaskErrors(self.labelled_px + other.labelled_px, self.missed_px + other.missed_px,
                          self.false_px + other.false_px, on)

    @property
    def iou(self) -> float:
        """IoU of the summed counts: (labelled - missed) / (labelled + false); nan when both are 0."""
        union = self.labelled_px + self.false_px
        return (self.labelled_px - self.missed_px) / union if union else float("nan")

    def summary(self) -> str:
        """One line: missed and false pixels as fractions of the labelled pixels."""
        if not self.labelled_px:
            return "no labelled pixels"
        frac = lambda n: n / self.labelled_px                                     # noqa: E731
        on = ", ".join(f"on {name} {frac(n):.3f}" for name, n in sorted(self.false_px_on.items()))
        return (f"of {self.labelled_px} labelled px: missed {frac(self.missed_px):.3f}; false px "
                f"{frac(self.false_px):.3f} of that number ({on}); pooled IoU {self.iou:.3f}")


def mask_errors(predicted: np.ndarray, labelled: np.ndarray,
                other_labels: Mapping[str, np.ndarray] = None) -> MaskErrors:
    """MaskErrors of an (H, W) bool predicted mask against the (H, W) bool labelled mask.

    other_labels: name -> (H, W) bool mask of each other labelled class; a
    false pixel counts for every such mask it lies on.
    Raises ValueError for masks that are not 2-D or differ in size.
    """
    pred, lab = np.asarray(predicted, dtype=bool), np.asarray(labelled, dtype=bool)
    if pred.ndim != 2 or pred.shape != lab.shape:
        raise ValueError(f"predicted and labelled masks must be the same (H, W), got {pred.shape} and {lab.shape}")
    false = pred & ~lab
    on = {}
    for name, other in (other_labels or {}).items():
        other = np.asarray(other, dtype=bool)
        if other.shape != lab.shape:
            raise ValueError(f"label mask {name!r} is {other.shape}, expected {lab.shape}")
        on[name] = int((false & other).sum())
    return MaskErrors(int(lab.sum()), int((lab & ~pred).sum()), int(false.sum()), on)
