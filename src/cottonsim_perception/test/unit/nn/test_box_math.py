"""DFL decode, CIoU, the task-aligned assigner, NMS and the letterbox, against hand-computed values."""
import math

import numpy as np
import pytest
import torch

from cottonsim_perception.nn.assigner import AssignerConfig, TaskAlignedAssigner, bbox_iou
from cottonsim_perception.nn.heads import dfl_expectation, dist_to_xyxy, make_anchors, xyxy_to_dist
from cottonsim_perception.nn.letterbox import LetterboxTransform, letterbox
from cottonsim_perception.nn.postprocess import batched_nms, nms, PostprocessConfig, postprocess


def test_dfl_expectation_of_known_distributions():
    reg_max = 16
    logits = torch.full((1, 4 * reg_max), -1e4)
    # side 0: all mass on bin 5 -> 5; side 1: half on 3, half on 4 -> 3.5
    # side 2: uniform -> 7.5; side 3: 1/4 on bin 0 and 3/4 on bin 8 -> 6
    logits[0, 5] = 0.0
    logits[0, 16 + 3] = 0.0
    logits[0, 16 + 4] = 0.0
    logits[0, 32:48] = 0.0
    logits[0, 48 + 0] = math.log(0.25)
    logits[0, 48 + 8] = math.log(0.75)
    d = dfl_expectation(logits, reg_max)
    assert torch.allclose(d, torch.tensor([[5.0, 3.5, 7.5, 6.0]]), atol=1e-4)


def test_anchor_points_and_distance_round_trip():
    feats = [torch.zeros(1, 1, 2, 3), torch.zeros(1, 1, 1, 2)]
    pts, strides = make_anchors(feats, (8, 16))
    assert pts.shape == (8, 2) and strides.shape == (8, 1)
    assert pts[:3].tolist() == [[0.5, 0.5], [1.5, 0.5], [2.5, 0.5]] and pts[3].tolist() == [0.5, 1.5]
    assert strides[:6].flatten().tolist() == [8.0] * 6 and strides[6:].flatten().tolist() == [16.0] * 2
    box = torch.tensor([[0.0, 0.0, 2.0, 1.0]])
    d = xyxy_to_dist(box, pts[:1], 15.0)
    assert d.tolist() == [[0.5, 0.5, 1.5, 0.5]]
    assert torch.equal(dist_to_xyxy(d, pts[:1]), box)


def test_iou_and_ciou_of_known_boxes():
    a = torch.tensor([0.0, 0.0, 2.0, 2.0])
    b = torch.tensor([1.0, 1.0, 3.0, 3.0])
    # IoU = 1 / 7; enclosing box 3 x 3 -> c^2 = 18; centre distance^2 = 2; same aspect -> v = 0
    assert bbox_iou(a, b).item() == pytest.approx(1 / 7, abs=1e-6)
    assert bbox_iou(a, b, ciou=True).item() == pytest.approx(1 / 7 - 2 / 18, abs=1e-6)
    c = torch.tensor([0.0, 0.0, 4.0, 2.0])
    d = torch.tensor([0.0, 0.0, 2.0, 2.0])
    # IoU = 4 / 8; enclosing 4 x 2 -> c^2 = 20; centres (2, 1), (1, 1) -> 1
    v = 4 / math.pi ** 2 * (math.atan(1.0) - math.atan(2.0)) ** 2
    alpha = v / (1 - 0.5 + v)
    assert bbox_iou(c, d, ciou=True).item() == pytest.approx(0.5 - 1 / 20 - alpha * v, abs=1e-6)
    assert bbox_iou(a, a, ciou=True).item() == pytest.approx(1.0, abs=1e-6)


def _grid_points(n=8, stride=8.0):
    ys, xs = torch.meshgrid(torch.arange(n), torch.arange(n), indexing="ij")
    return (torch.stack((xs, ys), -1).reshape(-1, 2).float() + 0.5) * stride


def test_assigner_picks_the_anchors_inside_the_gt_box():
    pts = _grid_points()                                    # centres 4, 12, ..., 60
    gt = torch.tensor([[[10.0, 10.0, 30.0, 30.0]]])
    a = pts.shape[0]
    scores = torch.full((1, a, 2), 0.5)
    pred = gt.expand(1, a, 4).clone()                       # every prediction is perfect
    asg = TaskAlignedAssigner(AssignerConfig(top_k=10))(scores, pred, pts, torch.tensor([[1]]), gt,
                                                        torch.tensor([[True]]))
    inside = {(x, y) for x in (12.0, 20.0, 28.0) for y in (12.0, 20.0, 28.0)}
    chosen = {tuple(p) for p in pts[asg.fg_mask[0]].tolist()}
    assert chosen == inside
    assert torch.all(asg.labels[0][asg.fg_mask[0]] == 1)
    # soft targets: only class 1 of positives, best anchor reaches the best IoU (1.0)
    assert asg.scores[0, ~asg.fg_mask[0]].abs().sum() == 0
    assert asg.scores[0, asg.fg_mask[0], 0].abs().sum() == 0
    assert asg.scores[0, :, 1].max().item() == pytest.approx(1.0, abs=1e-5)


def test_assigner_top_k_prefers_higher_iou_and_resolves_conflicts():
    pts = _grid_points()
    gt = torch.tensor([[[10.0, 10.0, 30.0, 30.0], [18.0, 18.0, 50.0, 50.0]]])
    a = pts.shape[0]
    scores = torch.full((1, a, 1), 0.5)
    # predictions: a box centred at each anchor, 20 px wide
    pred = torch.cat((pts - 10, pts + 10), -1)[None]
    asg = TaskAlignedAssigner(AssignerConfig(top_k=1))(scores, pred, pts, torch.tensor([[0, 0]]), gt,
                                                       torch.tensor([[True, True]]))
    fg = asg.fg_mask[0]
    assert int(fg.sum()) == 2
    # gt 0's best anchor is the one at its centre (20, 20): its predicted box equals the gt
    idx0 = int(((pts - torch.tensor([20.0, 20.0])).abs().sum(-1) == 0).nonzero())
    assert fg[idx0] and asg.gt_index[0, idx0] == 0
    # padded (invalid) gts assign nothing
    none = TaskAlignedAssigner()(scores, pred, pts, torch.tensor([[0]]), gt[:, :1],
                                 torch.tensor([[False]]))
    assert not none.fg_mask.any()


def test_nms_removes_overlapping_lower_score_and_keeps_distinct():
    boxes = torch.tensor([[0.0, 0.0, 10.0, 10.0], [1.0, 1.0, 11.0, 11.0], [20.0, 20.0, 30.0, 30.0]])
    scores = torch.tensor([0.8, 0.9, 0.7])
    # IoU(0, 1) = 81 / 119 = 0.68
    assert nms(boxes, scores, 0.5).tolist() == [1, 2]
    assert nms(boxes, scores, 0.7).tolist() == [1, 0, 2]
    # boxes of different classes never suppress each other
    assert sorted(batched_nms(boxes, scores, torch.tensor([0, 1, 0]), 0.5).tolist()) == [0, 1, 2]


def test_letterbox_geometry_and_box_round_trip():
    img = np.zeros((540, 720, 3), np.uint8)
    out, t = letterbox(img, 320, 256)
    # scale = min(320 / 720, 256 / 540) = 4/9 -> 320 x 240, 8 px bars top and bottom
    assert out.shape == (256, 320, 3)
    assert (t.content_width, t.content_height, t.pad_left, t.pad_top) == (320, 240, 0, 8)
    assert out[0, 0, 0] == 114 and out[100, 100, 0] == 0
    # original box (72, 54)-(144, 108) is input box (72 * 4/9, 54 * 4/9 + 8)-(144 * 4/9, 108 * 4/9 + 8)
    box = np.array([[72.0, 54.0, 144.0, 108.0]])
    inp = np.array([[32.0, 32.0, 64.0, 56.0]])
    assert np.allclose(t.affine() @ np.array([[72.0, 144.0], [54.0, 108.0], [1.0, 1.0]]), inp.reshape(2, 2).T)
    assert np.allclose(t.boxes_to_original(inp), box)


def test_letterbox_mask_inverse_on_proto_grid():
    t = LetterboxTransform.fit(720, 540, 320, 256)
    # a soft mask on the quarter-resolution grid (80 x 64) covering input box (32, 32, 64, 56)
    m = torch.zeros(1, 64, 80)
    m[0, 8:14, 8:16] = 1.0
    out = t.masks_to_original(m)
    assert out.shape == (1, 540, 720)
    ys, xs = np.nonzero(out[0])
    # original box (72, 54, 144, 108): bilinear edges may move by about one original pixel per side
    assert abs(xs.min() - 72) <= 3 and abs(xs.max() + 1 - 144) <= 3
    assert abs(ys.min() - 54) <= 3 and abs(ys.max() + 1 - 108) <= 3


def test_postprocess_decodes_filters_and_maps_masks_back():
    t = LetterboxTransform.fit(720, 540, 320, 256)
    # three anchors, one class, one prototype that is +10 everywhere (mask prob ~1 inside the box)
    pred = torch.tensor([[[32.0, 32.0, 64.0, 56.0, 0.9, 1.0],
                          [33.0, 33.0, 65.0, 57.0, 0.6, 1.0],     # duplicate, lower score
                          [100.0, 100.0, 140.0, 140.0, 0.1, 1.0]]])  # below threshold
    protos = torch.full((1, 1, 64, 80), 10.0)
    det = postprocess(pred, 1, [t], protos, PostprocessConfig(conf_threshold=0.25, iou_threshold=0.5))[0]
    assert len(det) == 1
    assert np.allclose(det.boxes_xyxy[0], [72.0, 54.0, 144.0, 108.0], atol=1e-3)
    assert det.scores.dtype == np.float32 and det.classes.tolist() == [0]
    assert det.masks.shape == (1, 540, 720)
    area = det.masks[0].sum()
    assert abs(area - 72 * 54) / (72 * 54) < 0.1
    assert not det.masks[0, :40].any() and not det.masks[0, :, 160:].any()


def test_postprocess_config_validation():
    with pytest.raises(ValueError, match="iou_threshold"):
        PostprocessConfig(iou_threshold=1.5)
