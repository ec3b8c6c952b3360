"""The loss falls when a small network overfits one synthetic image (a white square on black)."""
import pytest
import torch

from cottonsim_perception.nn.loss import LossConfig, YoloLoss, dfl_loss, soft_dice_loss
from cottonsim_perception.nn.models import ModelConfig, build_model

H, W = 64, 96


def _square_batch():
    img = torch.zeros(1, 3, H, W)
    img[:, :, 16:48, 32:72] = 1.0
    mask = torch.zeros(1, H, W)
    mask[0, 16:48, 32:72] = 1.0
    targets = {"batch_idx": torch.tensor([0]), "classes": torch.tensor([0]),
               "boxes_xyxy": torch.tensor([[32.0, 16.0, 72.0, 48.0]]), "masks": mask}
    return img, targets


def test_dfl_loss_is_smallest_for_the_right_bins():
    reg_max = 16
    target = torch.tensor([[3.25, 3.25, 3.25, 3.25]])
    good = torch.full((1, 4 * reg_max), -20.0)
    for s in range(4):
        good[0, s * reg_max + 3] = 0.0 + torch.log(torch.tensor(0.75))
        good[0, s * reg_max + 4] = 0.0 + torch.log(torch.tensor(0.25))
    bad = torch.zeros(1, 4 * reg_max)
    # the ideal distribution (0.75, 0.25) reaches the cross-entropy minimum H = -(.75 ln .75 + .25 ln .25)
    h = -(0.75 * torch.log(torch.tensor(0.75)) + 0.25 * torch.log(torch.tensor(0.25)))
    assert dfl_loss(good, target, reg_max).item() == pytest.approx(h.item(), abs=1e-4)
    assert dfl_loss(bad, target, reg_max).item() > h.item() + 1.0


@pytest.mark.parametrize("task", ["det", "seg"])
def test_loss_decreases_when_overfitting_one_image(task):
    torch.manual_seed(0)
    cfg = ModelConfig(task=task, num_classes=1, class_names=("square",), input_width=W, input_height=H,
                      width_multiple=0.0625, num_prototypes=4, proto_channels=8)
    model = build_model(cfg).train()
    loss_fn = YoloLoss(1, cfg.reg_max)
    opt = torch.optim.AdamW(model.parameters(), lr=3e-3)
    img, targets = _square_batch()
    if task == "det":
        targets = {k: v for k, v in targets.items() if k != "masks"}
    losses = []
    for _ in range(25):
        loss, parts = loss_fn(model(img), targets)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert set(parts) == ({"box", "cls", "dfl", "mask"} if task == "seg" else {"box", "cls", "dfl"})
    assert losses[-1] < 0.4 * losses[0], losses


def test_loss_without_targets_only_pushes_scores_down():
    cfg = ModelConfig(task="det", num_classes=1, class_names=("a",), input_width=64, input_height=64,
                      width_multiple=0.0625)
    model = build_model(cfg).train()
    empty = {"batch_idx": torch.zeros(0, dtype=torch.long), "classes": torch.zeros(0, dtype=torch.long),
             "boxes_xyxy": torch.zeros(0, 4)}
    loss, parts = YoloLoss(1)(model(torch.rand(2, 3, 64, 64)), empty)
    assert parts["box"] == 0.0 and parts["dfl"] == 0.0 and parts["cls"] > 0.0
    loss.backward()


def test_bad_targets_and_config_are_clear_errors():
    with pytest.raises(ValueError, match="box_gain"):
        LossConfig(box_gain=-1.0)
    cfg = ModelConfig(task="seg", num_classes=1, class_names=("a",), input_width=64, input_height=64,
                      width_multiple=0.0625)
    out = build_model(cfg).train()(torch.rand(1, 3, 64, 64))
    with pytest.raises(ValueError, match="masks"):
        YoloLoss(1)(out, {"batch_idx": torch.tensor([0]), "classes": torch.tensor([0]),
                          "boxes_xyxy": torch.tensor([[0.0, 0.0, 8.0, 8.0]])})


def test_ignore_boxes_remove_only_the_background_loss_inside_them():
    from cottonsim_perception.nn.loss import anchors_in_ignore_boxes
    cfg = ModelConfig(task="det", num_classes=1, class_names=("a",), input_width=64, input_height=64,
                      width_multiple=0.0625)
    model = build_model(cfg).train()
    out = model(torch.rand(2, 3, 64, 64))
    empty = {"batch_idx": torch.zeros(0, dtype=torch.long), "classes": torch.zeros(0, dtype=torch.long),
             "boxes_xyxy": torch.zeros(0, 4)}
    loss_fn = YoloLoss(1)
    _, plain = loss_fn(out, empty)
    # a whole-image ignore box on image 0: only image 1's background loss is left
    whole = dict(empty, ignore_batch_idx=torch.tensor([0]), ignore_boxes_xyxy=torch.tensor([[0.0, 0.0, 64.0, 64.0]]))
    _, half = loss_fn(out, whole)
    _, only_img1 = loss_fn(tuple(m[1:] for m in out) if isinstance(out, tuple) else [m[1:] for m in out], empty)
    assert 0.0 < half["cls"] < plain["cls"]
    assert half["cls"] == pytest.approx(only_img1["cls"], rel=1e-5)
    # a box smaller than a cell still covers the anchor of its cell (stride 8: centre (4, 4))
    centres = torch.tensor([[4.0, 4.0], [12.0, 4.0]])
    strides = torch.tensor([[8.0], [8.0]])
    got = anchors_in_ignore_boxes(centres, strides, 2, torch.tensor([1]), torch.tensor([[1.0, 1.0, 3.0, 3.0]]))
    assert got.tolist() == [[False, False], [True, False]]
    with pytest.raises(ValueError, match="ignore"):
        anchors_in_ignore_boxes(centres, strides, 2, torch.tensor([0, 1]), torch.tensor([[1.0, 1.0, 3.0, 3.0]]))


def test_soft_dice_loss_scores_the_overlap_inside_the_region_only():
    target = torch.zeros(2, 8, 8)
    target[:, 2:6, 3] = 1.0                                   # a 1-px "stem", 4 px long
    inside = torch.zeros(2, 8, 8, dtype=torch.bool)
    inside[:, 1:7, 1:7] = True
    logits = torch.full((2, 8, 8), -30.0)
    logits[0, 2:6, 3] = 30.0                                  # mask 0: exactly the stem
    logits[0, 0, 0] = 30.0                                    # ... plus a pixel outside the region
    logits[1, 2:6, 4] = 30.0                                  # mask 1: beside it, no overlap
    loss = soft_dice_loss(logits, target, inside)
    assert loss[0].item() == pytest.approx(0.0, abs=1e-6)
    assert loss[1].item() == pytest.approx(1.0 - 1.0 / 9.0, abs=1e-6)   # 1 - (0 + 1) / (4 + 4 + 1)
    # an empty target with an empty prediction is no loss
    assert soft_dice_loss(torch.full((1, 8, 8), -30.0), torch.zeros(1, 8, 8), inside[:1]).item() == \
        pytest.approx(0.0, abs=1e-6)


def test_mask_dice_weight_adds_the_dice_term_to_the_mask_loss():
    torch.manual_seed(0)
    cfg = ModelConfig(task="seg", num_classes=1, class_names=("a",), input_width=W, input_height=H,
                      width_multiple=0.0625)
    model = build_model(cfg).train()
    img, targets = _square_batch()
    out = model(img)
    _, plain = YoloLoss(1, config=LossConfig())(out, targets)
    total, dice = YoloLoss(1, config=LossConfig(mask_dice_weight=2.0))(out, targets)
    # an untrained mask overlaps the square poorly: the Dice term is positive, at most the weight
    assert plain["mask"] < dice["mask"] <= plain["mask"] + 2.0
    total.backward()
    for bad in (-0.1, float("nan"), True):
        with pytest.raises(ValueError, match="mask_dice_weight"):
            LossConfig(mask_dice_weight=bad)
