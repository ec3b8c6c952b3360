"""Why a detector's boxes fail IoU 0.5: its misses and false positives, sorted by kind.

mAP50 counts the boxes that pass IoU 0.5 and says nothing about the rest. The
kind of failure decides what to try next. A labelled box with a prediction at
IoU 0.3-0.5 was found, but the box was drawn in the wrong place or at the
wrong size; with the boll detector this is often two touching bolls merged
into one box, or split differently from the labels. A labelled box with no
prediction near it is an object the network did not see at all.

Rules, per image:

* Predictions at or above the confidence threshold (the caller's) are matched
  one-to-one to same-class labelled boxes at ``match_iou``. They are taken in
  descending score, as the AP matches them (``metrics.match_predictions``,
  method 'score').
* Every unmatched labelled box is a miss. Its kind comes from the best IoU of
  any same-class prediction with it, matched or not:
  'misplaced' when that IoU >= ``near_iou``, 'weak' when >= ``weak_iou``,
  'unseen' below.
* A labelled box *touches* when it intersects another labelled box or an
  ignore box (any class).
* Every unmatched prediction is a false positive, unless it lies on an ignore
  box (the AP's rule, ``metrics.on_ignore_regions``). It is 'near a label'
  when its IoU with some same-class labelled box is >= ``near_iou`` (a
  duplicate or a misplaced box), else 'background'.

:class:`BoxMatch` matches one image once; its ``errors()`` counts the above
(:class:`BoxErrors`, summed with ``+``) and its ``misses_by_size()`` counts
labelled and missed boxes by size bin (the box's longer side) and by touching,
for the miss-rate table of ``scripts/box_errors``. :func:`box_errors` and
:func:`misses_by_size` do either for one image.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Dict, Optional

import numpy as np

from cottonsim_common.validation import require_instance
from cottonsim_perception.evaluation.metrics import as_boxes, assign_by_score, box_iou, on_ignore_regions

MISS_KINDS = ("misplaced", "weak", "unseen")


@dataclass(frozen=True)
class BoxErrorConfig:
    """IoU cut-offs of :func:`box_errors`.

    match_iou: a prediction finds a labelled box at this IoU (the AP50's 0.5);
    near_iou: a miss with a prediction at this IoU or more is 'misplaced', and a
        false positive this close to a labelled box is 'near a label';
    weak_iou: a miss with a best prediction IoU in [weak_iou, near_iou) is 'weak', below it 'unseen'.
    """

    match_iou: float = 0.5
    near_iou: float = 0.3
    weak_iou: float = 0.1

    def __post_init__(self) -> None:
        for name in ("match_iou", "near_iou", "weak_iou"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 < v <= 1.0:
                raise ValueError(f"{name} must be a number in (0, 1], got {v!r}")
        if not self.weak_iou <= self.near_iou <= self.match_iou:
            raise ValueError(f"need weak_iou <= near_iou <= match_iou, got {self.weak_iou}, {self.near_iou}, "
                             f"{self.match_iou}")


@dataclass(frozen=True)
class BoxErrors:
    """Counts over one or more images (add two with ``+``).

    labelled: labelled boxes; touching: of these, the ones that intersect another labelled or ignore box;
    found: labelled boxes matched at match_iou;
    misplaced, weak, unseen: misses by the best prediction IoU (see the module docstring), and
    misplaced_touching, weak_touching, unseen_touching: how many of each touch;
    false_positives: unmatched predictions not on an ignore box; fp_near_label: of these, the ones at
    IoU >= near_iou with a labelled box; fp_background: the others; on_ignore: unmatched predictions on an
    ignore box (neither true nor false positives).
    """

    labelled: int = 0
    touching: int = 0
    found: int = 0
    misplaced: int = 0
    weak: int = 0
    unseen: int = 0
    misplaced_touching: int = 0
    weak_touching: int = 0
    unseen_touching: int = 0
    false_positives: int = 0
    fp_near_label: int = 0
    fp_background: int = 0
    on_ignore: int = 0

    def __add__(self, other: "BoxErrors") -> "BoxErrors":
        if not isinstance(other, BoxErrors):
            return NotImplemented
        return BoxErrors(**{f.name: getattr(self, f.name) + getattr(other, f.name) for f in fields(self)})

    @property
    def missed(self) -> int:
        return self.misplaced + self.weak + self.unseen

    def as_dict(self) -> Dict[str, int]:
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["missed"] = self.missed
        return out


def check_size_edges(size_edges_px) -> np.ndarray:
    """The size bins' edges [px] as a float array; ValueError unless increasing positive numbers."""
    edges = np.asarray(size_edges_px, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(edges)) or np.any(edges <= 0) or np.any(np.diff(edges) <= 0):
        raise ValueError(f"size_edges_px must be increasing positive numbers, got {tuple(size_edges_px)!r}")
    return edges


class BoxMatch:
    """One image's predictions matched to its labelled boxes (see the module docstring); count them with
    :meth:`errors` and :meth:`misses_by_size`, which share this one matching.

    pred_boxes (N, 4) xyxy [px], pred_scores (N,), pred_classes (N,): the predictions to score (already
    cut at the caller's confidence); gt_boxes (M, 4), gt_classes (M,): the labelled boxes; ignore_boxes
    (K, 4) or None: don't-care regions. Raises ValueError for mismatched shapes or non-finite boxes.
    """

    def __init__(self, pred_boxes, pred_scores, pred_classes, gt_boxes, gt_classes, ignore_boxes=None,
                 config: BoxErrorConfig = BoxErrorConfig()):
        require_instance("config", config, BoxErrorConfig)
        self.config = config
        p = as_boxes("pred_boxes", pred_boxes)
        g = as_boxes("gt_boxes", gt_boxes)
        ign = as_boxes("ignore_boxes", ignore_boxes if ignore_boxes is not None else np.zeros((0, 4)))
        ps = np.asarray(pred_scores, dtype=np.float64).reshape(-1)
        pc = np.asarray(pred_classes).reshape(-1)
        gc = np.asarray(gt_classes).reshape(-1)
        if ps.size != p.shape[0] or pc.size != p.shape[0]:
            raise ValueError(f"{p.shape[0]} predicted boxes with {ps.size} scores and {pc.size} classes")
        if gc.size != g.shape[0]:
            raise ValueError(f"{g.shape[0]} labelled boxes with {gc.size} classes")
        iou = box_iou(p, g)
        same = pc[:, None] == gc[None, :]
        self.iou_same = np.where(same, iou, 0.0)
        assigned = assign_by_score(np.where(same, iou, -1.0), ps, config.match_iou)
        self.matched_pred = assigned >= 0
        self.found = np.zeros(g.shape[0], dtype=bool)
        self.found[assigned[self.matched_pred]] = True
        # a labelled box touches when it intersects another labelled box or an ignore box
        inter = box_iou(g, np.concatenate([g, ign])) > 0
        inter[np.arange(g.shape[0]), np.arange(g.shape[0])] = False
        self.touching = inter.any(axis=1)
        self.best_iou = self.iou_same.max(axis=0) if p.shape[0] else np.zeros(g.shape[0])
        self.ignored = (on_ignore_regions(p, self.matched_pred, ign) if ign.shape[0]
                        else np.zeros(p.shape[0], dtype=bool))
        self.side_px = np.maximum(g[:, 2] - g[:, 0], g[:, 3] - g[:, 1])

    def errors(self) -> BoxErrors:
        """The :class:`BoxErrors` of this image."""
        config = self.config
        counts = {k: 0 for k in MISS_KINDS}
        counts_touching = {k: 0 for k in MISS_KINDS}
        for j in np.nonzero(~self.found)[0]:
            b = self.best_iou[j]
            kind = "misplaced" if b >= config.near_iou else ("weak" if b >= config.weak_iou else "unseen")
            counts[kind] += 1
            counts_touching[kind] += int(self.touching[j])
        unmatched = ~self.matched_pred
        fp = unmatched & ~self.ignored
        near = (self.iou_same.max(axis=1) >= config.near_iou if self.iou_same.shape[1]
                else np.zeros(fp.shape, dtype=bool))
        return BoxErrors(
            labelled=int(self.found.size), touching=int(self.touching.sum()), found=int(self.found.sum()),
            misplaced=counts["misplaced"], weak=counts["weak"], unseen=counts["unseen"],
            misplaced_touching=counts_touching["misplaced"], weak_touching=counts_touching["weak"],
            unseen_touching=counts_touching["unseen"],
            false_positives=int(fp.sum()), fp_near_label=int((fp & near).sum()),
            fp_background=int((fp & ~near).sum()), on_ignore=int((unmatched & self.ignored).sum()))

    def misses_by_size(self, size_edges_px=(12.0, 16.0, 24.0, 32.0)) -> np.ndarray:
        """Labelled and missed boxes by size and by touching: (B, 2, 2) int array.

        ``[b, t, 0]`` counts the labelled boxes of size bin b (their longer side [px]; bins split at the
        increasing ``size_edges_px``, so B = len(size_edges_px) + 1) that touch (t = 1) or not (t = 0)
        another box; ``[b, t, 1]`` how many of them were missed. Sum the arrays of many images for a table.
        """
        edges = check_size_edges(size_edges_px)
        out = np.zeros((edges.size + 1, 2, 2), dtype=np.int64)
        bins = np.searchsorted(edges, self.side_px, side="right")
        np.add.at(out, (bins, self.touching.astype(int), 0), 1)
        np.add.at(out, (bins, self.touching.astype(int), 1), (~self.found).astype(int))
        return out


def box_errors(pred_boxes, pred_scores, pred_classes, gt_boxes, gt_classes, ignore_boxes=None,
               config: BoxErrorConfig = BoxErrorConfig()) -> BoxErrors:
    """The :class:`BoxErrors` of one image (arguments as :class:`BoxMatch`)."""
    return BoxMatch(pred_boxes, pred_scores, pred_classes, gt_boxes, gt_classes, ignore_boxes, config).errors()


def misses_by_size(pred_boxes, pred_scores, pred_classes, gt_boxes, gt_classes, ignore_boxes=None,
                   size_edges_px=(12.0, 16.0, 24.0, 32.0), config: BoxErrorConfig = BoxErrorConfig()) -> np.ndarray:
    """:meth:`BoxMatch.misses_by_size` of one image (arguments as :class:`BoxMatch`)."""
    return BoxMatch(pred_boxes, pred_scores, pred_classes, gt_boxes, gt_classes, ignore_boxes,
                    config).misses_by_size(size_edges_px)


def format_misses_by_size(table: np.ndarray, size_edges_px) -> str:
    """``misses_by_size`` (summed over images) as text: one line per size bin, miss rate alone / touching."""
    edges = [0.0] + [float(e) for e in size_edges_px] + [float("inf")]
    if table.shape != (len(edges) - 1, 2, 2):
        raise ValueError(f"table of shape {table.shape} does not fit {len(edges) - 2} size edges")
    rate = (lambda n, d: f"{100.0 * n / d:5.1f} % of {d:4d}" if d else "     - of    0")
    lines = ["  misses by box size (longer side) [px]: standing alone | touching another box"]
    for b in range(len(edges) - 1):
        lo, hi = edges[b], edges[b + 1]
        name = f"{lo:g}-{hi:g}" if np.isfinite(hi) else f">= {lo:g}"
        lines.append(f"    {name:>8}: {rate(table[b, 0, 1], table[b, 0, 0])} | {rate(table[b, 1, 1], table[b, 1, 0])}")
    return "\n".join(lines)


def format_box_errors(errors: BoxErrors, config: BoxErrorConfig = BoxErrorConfig(),
                      title: Optional[str] = None) -> str:
    """A short plain-text report of ``errors`` (``config``: the cut-offs they were counted with)."""
    e, c = errors, config
    pct = (lambda n, d: f"{100.0 * n / d:.1f} %" if d else "-")
    lines = [title] if title else []
    lines += [
        f"labelled boxes {e.labelled} (touching another box: {e.touching}, {pct(e.touching, e.labelled)}); "
        f"found {e.found} ({pct(e.found, e.labelled)}), missed {e.missed}",
        f"  misses: misplaced (a prediction at IoU {c.near_iou:g}-{c.match_iou:g}) {e.misplaced} ({e.misplaced_touching} touching), "
        f"weak (IoU {c.weak_iou:g}-{c.near_iou:g}) {e.weak} ({e.weak_touching} touching), unseen {e.unseen} ({e.unseen_touching} touching)",
        f"  false positives {e.false_positives}: near a label (IoU >= {c.near_iou:g}) {e.fp_near_label}, background {e.fp_background}; "
        f"on ignore boxes (not counted) {e.on_ignore}",
    ]
    return "\n".join(lines)
