"""Detection / instance-segmentation metrics: IoU, matching, P, R, AP, mAP.

Why: to compare our Cotton-Eye models with the paper's Table 3 we must compute
the numbers the way the paper's tool (Ultralytics YOLOv8 ``val``) did, and
know how that relates to the formulas the paper prints.

What the paper writes (Section 2.7)
-----------------------------------
* Eq. 1 ``P = TP / (TP + FP)``, Eq. 2 ``R = TP / (TP + FN)``, counted over the
  predicted and ground-truth instances at IoU 0.5.
* Eq. 3 ``AP = 1 / sum(r_i) * sum_i r_i * (sum_{j<=i} r_j / i)`` with r_i = 1 when
  the i-th prediction (in descending confidence) is correct. That is the
  precision at the rank of every true positive, averaged over the true
  positives. Note the normaliser: the number of *true positives*, not of
  ground-truth instances, so Eq. 3 as printed ignores missed objects (a model
  that finds one object out of ten, with confidence above all its false
  positives, gets AP = 1). :func:`ap_eq3` computes it literally; we report
  it as ``ap50_eq3`` for reference only.
* mAP = mean over classes of AP at IoU 0.5.

What the paper's numbers are (Ultralytics YOLOv8 val), and what we compute
--------------------------------------------------------------------------
The Table 3 values come from Ultralytics: e.g. 'ground' mAP50 = 99.5 % is
exactly Ultralytics' AP of a *perfect* class (see below), and 'all' R = 88.9 %
is the mean of the class recalls (66.7, 100, 100). We follow Ultralytics:

1. Matching (:func:`match_predictions`): per image and IoU threshold t, a
   prediction is a true positive when it is paired with a ground-truth
   instance of the same class with IoU >= t; each ground truth is paired at
   most once, so a duplicate detection is a false positive. Default method
   'score': predictions in descending score take the unmatched same-class
   ground truth of highest IoU (COCO's greedy rule). Method 'iou': pairs are
   taken in descending IoU (Ultralytics' rule). The two differ only when one
   ground truth is the best candidate of several overlapping predictions.
   Boxes use :func:`box_iou`, masks :func:`mask_iou` (Ultralytics compares masks
   at a quarter of the input resolution; we use the full original image).
   Our extension for simulator labels: a prediction that matches nothing and
   lies on an ignore box (:func:`on_ignore_regions`; bolls the labelling
   rules leave out) is dropped before step 2, as COCO drops detections on
   'crowd' regions. The paper's images have no ignore boxes.
2. Per class (:func:`ap_per_class`), predictions of all images sorted by
   descending confidence give the cumulative precision / recall curve.
   AP (:func:`compute_ap`, method 'ultralytics'): append (recall 0,
   precision 1) and (recall 1, precision 0), take the monotone envelope
   (precision made non-increasing in recall), sample it at 101 recall values
   0, 0.01, ..., 1 with linear interpolation and integrate with the trapezoid
   rule. A perfect class therefore scores 0.995, not 1 (the last 0.01 of
   recall interpolates down to the appended precision 0). Method 'coco' is
   COCO's rule: mean over the 101 recall values of the envelope's precision
   at recall >= r (0 where never reached); a perfect class scores 1.
3. P and R (Ultralytics' table): the per-class precision and recall curves
   are sampled on 1000 confidence values in [0, 1] (linear interpolation
   between predictions, P = 1 and R = 0 above the highest confidence); the
   confidence where the class-mean F1 (box-filtered over 10 % of the grid)
   is largest is chosen, and P and R of every class are read there. We also
   give the exact Eq. 1 / 2 counts TP, FP, FN of the predictions at or above
   that confidence.
4. mAP50 = mean over classes of AP at IoU 0.5; mAP50-95 = mean over classes
   and the 10 IoU thresholds 0.50:0.05:0.95. The 'all' row averages P, R,
   AP over the classes that have ground truth (classes without ground truth
   are left out, as in Ultralytics; their predictions then count nowhere).
   A class with ground truth but no prediction scores 0.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict

import numpy as np

#: IoU thresholds 0.50, 0.55, ..., 0.95 of mAP50-95.
IOU_THRESHOLDS = np.round(np.linspace(0.5, 0.95, 10), 2)

#: Share of a prediction's box inside an ignore box that makes it "on" the ignore region.
IGNORE_MIN_IOA = 0.5

_EPS = 1e-16


def as_boxes(name: str, boxes) -> np.ndarray:
    """``boxes`` as a (N, 4) float64 array ((0, 4) when empty); ValueError naming ``name`` otherwise."""
    b = np.asarray(boxes, dtype=np.float64)
    if b.size == 0:
        return b.reshape(0, 4)
    if b.ndim != 2 or b.shape[1] != 4:
        raise ValueError(f"{name} must be (N, 4) boxes, got shape {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ValueError(f"{name} contains NaN or inf")
    return b


def _pairwise_intersection(boxes_a, boxes_b):
    """(N, M) intersection areas of (N, 4) and (M, 4) xyxy boxes, and their (N,), (M,) areas."""
    a = as_boxes("boxes_a", boxes_a)
    b = as_boxes("boxes_b", boxes_b)
    area_a = np.clip(a[:, 2] - a[:, 0], 0, None) * np.clip(a[:, 3] - a[:, 1], 0, None)
    area_b = np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None)
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    wh = np.clip(rb - lt, 0, None)
    return wh[..., 0] * wh[..., 1], area_a, area_b


def box_iou(boxes_a, boxes_b) -> np.ndarray:
    """IoU of every pair of (x1, y1, x2, y2) boxes: (N, 4), (M, 4) -> (N, M) float64.

    Degenerate boxes (zero area) have IoU 0 with everything.
    """
    inter, area_a, area_b = _pairwise_intersection(boxes_a, boxes_b)
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.maximum(union, _EPS), 0.0)


def box_ioa(boxes_a, boxes_b) -> np.ndarray:
    """Intersection over the area of a of every pair of boxes: (N, 4), (M, 4) -> (N, M).

    How much of each box a lies inside box b (1 when a is inside b); a
    degenerate a gives 0.
    """
    inter, area_a, _ = _pairwise_intersection(boxes_a, boxes_b)
    return np.where(area_a[:, None] > 0, inter / np.maximum(area_a[:, None], _EPS), 0.0)


def on_ignore_regions(pred_boxes, matched_at_first_threshold, ignore_boxes,
                      min_ioa: float = IGNORE_MIN_IOA) -> np.ndarray:
    """Which predictions to leave out of P / R / AP because they lie on a don't-care region.

    A prediction is left out when it matched no ground truth at the first
    (loosest) IoU threshold and at least ``min_ioa`` of its box lies inside
    one ignore box (COCO's rule for 'crowd' regions, here for objects the
    labelling rules exclude, e.g. bolls beyond the working range). Returns
    (N,) bool.
    """
    p = as_boxes("pred_boxes", pred_boxes)
    matched = np.asarray(matched_at_first_threshold, dtype=bool).reshape(-1)
    if matched.shape[0] != p.shape[0]:
        raise ValueError(f"{matched.shape[0]} match flags for {p.shape[0]} predictions")
    ign = as_boxes("ignore_boxes", ignore_boxes)
    if p.shape[0] == 0 or ign.shape[0] == 0:
        return np.zeros(p.shape[0], dtype=bool)
    return ~matched & (box_ioa(p, ign).max(axis=1) >= float(min_ioa))


def mask_iou(masks_a, masks_b, chunk: int = 64) -> np.ndarray:
    """IoU of every pair of masks: (N, H, W), (M, H, W) bool -> (N, M) float64.

    Intersections are a matrix product of the flattened masks, done in
    chunks of ``chunk`` masks to bound memory. Two empty masks have IoU 0.
    """
    a = np.asarray(masks_a)
    b = np.asarray(masks_b)
    if a.ndim != 3 or b.ndim != 3:
        raise ValueError(f"masks must be (N, H, W), got shapes {a.shape} and {b.shape}")
    if a.shape[1:] != b.shape[1:]:
        raise ValueError(f"mask sizes differ: {a.shape[1:]} vs {b.shape[1:]}")
    n, m = a.shape[0], b.shape[0]
    if n == 0 or m == 0:
        return np.zeros((n, m))
    fb = b.reshape(m, -1).astype(np.float32)
    area_b = fb.sum(axis=1).astype(np.float64)
    out = np.zeros((n, m))
    for s in range(0, n, max(1, int(chunk))):
        fa = a[s:s + chunk].reshape(-1, fb.shape[1]).astype(np.float32)
        inter = (fa @ fb.T).astype(np.float64)
        union = fa.sum(axis=1).astype(np.float64)[:, None] + area_b[None, :] - inter
        out[s:s + chunk] = np.where(union > 0, inter / np.maximum(union, _EPS), 0.0)
    return out


def assign_by_score(iou_same_class, scores, iou_threshold: float) -> np.ndarray:
    """The labelled box each prediction takes at one IoU threshold: (N,) index, -1 for none.

    iou_same_class (N, M): prediction x labelled-box IoU, negative (or 0) for pairs of different
    classes; scores (N,). Predictions in descending score each take the free labelled box of highest
    IoU >= iou_threshold (``match_predictions``' method 'score').
    """
    iou = np.asarray(iou_same_class, dtype=np.float64)
    if iou.ndim != 2:
        raise ValueError(f"assign_by_score: iou must be (N, M), got shape {iou.shape}")
    n, m = iou.shape
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    if s.size != n:
        raise ValueError(f"assign_by_score: {s.size} scores for {n} predictions")
    assigned = np.full(n, -1, dtype=np.int64)
    if n == 0 or m == 0:
        return assigned
    taken = np.zeros(m, dtype=bool)
    for i in np.argsort(-s, kind="stable"):
        cand = np.where(taken, -1.0, iou[i])
        j = int(np.argmax(cand))
        if cand[j] >= iou_threshold:
            taken[j] = True
            assigned[i] = j
    return assigned


def match_predictions(pred_classes, gt_classes, iou, iou_thresholds=IOU_THRESHOLDS,
                      scores=None, method: str = "score") -> np.ndarray:
    """True-positive flags of the predictions of one image: (N, T) bool.

    pred_classes (N,), gt_classes (M,), iou (N, M) prediction x ground truth,
    iou_thresholds (T,); scores (N,) needed for method 'score' (see module
    docstring): predictions in descending score each take the unmatched
    same-class ground truth of highest IoU >= t. Method 'iou': same-class
    pairs with IoU >= t are taken in descending IoU while both are free.
    """
    pc = np.asarray(pred_classes).reshape(-1)
    gc = np.asarray(gt_classes).reshape(-1)
    thr = np.asarray(iou_thresholds, dtype=np.float64).reshape(-1)
    n, m = pc.size, gc.size
    iou = np.asarray(iou, dtype=np.float64).reshape(n, m)
    correct = np.zeros((n, thr.size), dtype=bool)
    if n == 0 or m == 0:
        return correct
    same = pc[:, None] == gc[None, :]
    iou_same = np.where(same, iou, -1.0)
    if method == "score":
        if scores is None:
            raise ValueError("match_predictions: method 'score' needs scores")
        for ti, t in enumerate(thr):
            correct[:, ti] = assign_by_score(iou_same, scores, t) >= 0
    elif method == "iou":
        for ti, t in enumerate(thr):
            pi, gj = np.nonzero(iou_same >= t)
            if pi.size == 0:
                continue
            order = np.argsort(-iou_same[pi, gj], kind="stable")
            used_p = np.zeros(n, dtype=bool)
            used_g = np.zeros(m, dtype=bool)
            for k in order:
                i, j = pi[k], gj[k]
                if not used_p[i] and not used_g[j]:
                    used_p[i] = used_g[j] = True
                    correct[i, ti] = True
    else:
        raise ValueError(f"match_predictions: method must be 'score' or 'iou', got {method!r}")
    return correct


def compute_ap(recall, precision, method: str = "ultralytics") -> float:
    """Average precision of one precision / recall curve (in descending-score order).

    method 'ultralytics': trapezoid area under the envelope sampled at 101
    recall points, with (0, 1) and (1, 0) appended (perfect curve -> 0.995);
    'coco': mean of the envelope's precision at recall >= r for the 101
    values of r (perfect curve -> 1.0). See the module docstring.
    """
    r = np.asarray(recall, dtype=np.float64).reshape(-1)
    p = np.asarray(precision, dtype=np.float64).reshape(-1)
    if r.size != p.size:
        raise ValueError(f"compute_ap: recall ({r.size}) and precision ({p.size}) differ in length")
    x = np.linspace(0.0, 1.0, 101)
    if method == "ultralytics":
        mrec = np.concatenate(([0.0], r, [1.0]))
        mpre = np.concatenate(([1.0], p, [0.0]))
        mpre = np.maximum.accumulate(mpre[::-1])[::-1]
        y = np.interp(x, mrec, mpre)
        return float(np.sum((y[1:] + y[:-1]) * np.diff(x)) / 2.0)
    if method == "coco":
        if r.size == 0:
            return 0.0
        env = np.maximum.accumulate(p[::-1])[::-1]
        idx = np.searchsorted(r, x, side="left")
        q = np.where(idx < r.size, env[np.minimum(idx, r.size - 1)], 0.0)
        return float(q.mean())
    raise ValueError(f"compute_ap: method must be 'ultralytics' or 'coco', got {method!r}")


def ap_eq3(tp_in_score_order) -> float:
    """The paper's Eq. 3 taken literally: mean precision at the ranks of the true positives.

    tp_in_score_order: (N,) bool, r_i of the predictions sorted by descending
    confidence. Returns 0 when there is no true positive.
    """
    r = np.asarray(tp_in_score_order, dtype=np.float64).reshape(-1)
    if r.sum() == 0:
        return 0.0
    ranks = np.arange(1, r.size + 1)
    return float(np.sum(r * np.cumsum(r) / ranks) / r.sum())


def _box_filter(y: np.ndarray, fraction: float = 0.05) -> np.ndarray:
    """Moving average of odd width ~2*fraction*len(y), edges padded with the end values."""
    width = int(round(len(y) * fraction * 2)) // 2 * 2 + 1
    half = width // 2
    padded = np.concatenate([np.full(half, y[0]), y, np.full(half, y[-1])])
    return np.convolve(padded, np.ones(width) / width, mode="valid")


@dataclass(frozen=True)
class PerClassMetrics:
    """Metrics per class, arrays of length num_classes (classes without ground truth: NaN).

    n_gt: ground-truth instances; n_pred: predictions; ap: (C, T) AP per IoU
    threshold; p, r, f1: Ultralytics' P / R / F1 at ``conf_threshold``; tp, fp,
    fn: exact counts (Eq. 1 / 2) of predictions with confidence >= conf_threshold
    at IoU 0.5 (the first threshold); ap50_eq3: the paper's Eq. 3 at the first
    threshold; iou_thresholds: (T,).
    """

    n_gt: np.ndarray
    n_pred: np.ndarray
    ap: np.ndarray
    p: np.ndarray
    r: np.ndarray
    f1: np.ndarray
    tp: np.ndarray
    fp: np.ndarray
    fn: np.ndarray
    ap50_eq3: np.ndarray
    conf_threshold: float
    iou_thresholds: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """Classes that have ground truth (those the 'all' row averages)."""
        return self.n_gt > 0

    def summary(self) -> Dict[str, float]:
        """The 'all' row: mean P, R, mAP50, mAP50-95 over classes with ground truth."""
        v = self.valid
        if not v.any():
            return {"p": float("nan"), "r": float("nan"), "map50": float("nan"),
                    "map50_95": float("nan"), "ap50_eq3": float("nan")}
        return {"p": float(self.p[v].mean()), "r": float(self.r[v].mean()),
                "map50": float(self.ap[v, 0].mean()), "map50_95": float(self.ap[v].mean()),
                "ap50_eq3": float(self.ap50_eq3[v].mean())}


def ap_per_class(tp, conf, pred_classes, gt_classes, num_classes: int,
                 iou_thresholds=IOU_THRESHOLDS, ap_method: str = "ultralytics") -> PerClassMetrics:
    """Per-class AP / P / R from the matched predictions of a whole dataset.

    tp: (N, T) bool from :func:`match_predictions` (all images concatenated);
    conf: (N,) scores; pred_classes: (N,) ints; gt_classes: (M,) class of every
    ground-truth instance of the dataset; num_classes: C.
    """
    tp = np.asarray(tp, dtype=bool)
    conf = np.asarray(conf, dtype=np.float64).reshape(-1)
    pc = np.asarray(pred_classes).reshape(-1).astype(np.int64)
    gc = np.asarray(gt_classes).reshape(-1).astype(np.int64)
    thr = np.asarray(iou_thresholds, dtype=np.float64).reshape(-1)
    if tp.ndim != 2 or tp.shape != (conf.size, thr.size) or pc.size != conf.size:
        raise ValueError(f"ap_per_class: tp {tp.shape}, conf ({conf.size},), pred_classes "
                         f"({pc.size},) and {thr.size} thresholds do not agree")
    if num_classes <= 0:
        raise ValueError("ap_per_class: num_classes must be > 0")
    for name, arr in (("pred_classes", pc), ("gt_classes", gc)):
        if arr.size and (arr.min() < 0 or arr.max() >= num_classes):
            raise ValueError(f"ap_per_class: {name} outside 0..{num_classes - 1}")

    order = np.argsort(-conf, kind="stable")
    tp, conf, pc = tp[order], conf[order], pc[order]
    C, T = num_classes, thr.size
    grid = np.linspace(0.0, 1.0, 1000)
    n_gt = np.bincount(gc, minlength=C)
    n_pred = np.bincount(pc, minlength=C)
    ap = np.zeros((C, T))
    eq3 = np.zeros(C)
    p_curve = np.zeros((C, grid.size))
    r_curve = np.zeros((C, grid.size))
    for c in range(C):
        sel = pc == c
        if n_gt[c] == 0 or not sel.any():
            continue
        tpc = np.cumsum(tp[sel], axis=0)
        fpc = np.cumsum(~tp[sel], axis=0)
        recall = tpc / (n_gt[c] + _EPS)
        precision = tpc / (tpc + fpc)
        # np.interp needs increasing x: walk the grid from high to low confidence.
        r_curve[c] = np.interp(-grid, -conf[sel], recall[:, 0], left=0.0)
        p_curve[c] = np.interp(-grid, -conf[sel], precision[:, 0], left=1.0)
        for t in range(T):
            ap[c, t] = compute_ap(recall[:, t], precision[:, t], ap_method)
        eq3[c] = ap_eq3(tp[sel, 0])
    f1_curve = 2 * p_curve * r_curve / (p_curve + r_curve + _EPS)
    valid = n_gt > 0
    if valid.any():
        best = int(np.argmax(_box_filter(f1_curve[valid].mean(axis=0), 0.05)))
    else:
        best = 0
    conf_thr = float(grid[best])
    above = conf >= conf_thr
    tp_cnt = np.array([np.sum(tp[(pc == c) & above, 0]) if T else 0 for c in range(C)])
    fp_cnt = np.array([np.sum(~tp[(pc == c) & above, 0]) if T else 0 for c in range(C)])
    fn_cnt = n_gt - tp_cnt
    nan = np.where(valid, 1.0, np.nan)
    return PerClassMetrics(
        n_gt=n_gt, n_pred=n_pred, ap=ap * nan[:, None], p=p_curve[:, best] * nan,
        r=r_curve[:, best] * nan, f1=f1_curve[:, best] * nan, tp=tp_cnt, fp=fp_cnt,
        fn=fn_cnt, ap50_eq3=eq3 * nan, conf_threshold=conf_thr, iou_thresholds=thr)
