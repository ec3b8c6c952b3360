"""proto_stride 1: full-resolution masks from the stride-2 prototypes plus a detail path from the image.

Why these tests: the stride-1 segmenter must (a) give masks at the network
input size in train mode (the loss compares them with the labels there), (b)
start from a stride-2 checkpoint with exactly that network's masks, (c) give
in eval mode, per kept instance, the same mask logits as train mode's
full-resolution prototypes (postprocess never builds those), and (d) refuse
bad configurations with clear errors.
"""
import numpy as np
import pytest
import torch

from cottonsim_perception.nn.heads import Proto
from cottonsim_perception.nn.letterbox import LetterboxTransform
from cottonsim_perception.nn.loss import YoloLoss
from cottonsim_perception.nn.models import ModelConfig, build_model, save_checkpoint
from cottonsim_perception.nn.postprocess import PostprocessConfig, instance_mask_logits, postprocess

H, W = 96, 128
SMALL = dict(width_multiple=0.0625, input_width=W, input_height=H)


def _random_detail(model, seed=0):
    """Non-zero detail weights (they start at zero), so that the detail path is really exercised."""
    g = torch.Generator().manual_seed(seed)
    out = model.head.proto.detail_out
    with torch.no_grad():
        out.weight.copy_(torch.randn(out.weight.shape, generator=g) * 0.5)
        out.bias.copy_(torch.randn(out.bias.shape, generator=g) * 0.5)
    return model


def test_stride_one_prototypes_are_at_the_full_input_in_train_mode():
    torch.manual_seed(0)
    cfg = ModelConfig.scene_segmenter(proto_stride=1, detail_channels=4, **SMALL)
    model = build_model(cfg).train()
    maps, coeffs, protos = model(torch.rand(2, 3, H, W))
    assert protos.shape == (2, cfg.num_prototypes, H, W)
    assert coeffs.shape[:2] == (2, cfg.num_prototypes)
    assert tuple(model.head.proto.detail.conv.weight.shape) == (4, 3, 3, 3)


def test_eval_outputs_give_per_instance_the_train_mode_mask_logits():
    torch.manual_seed(0)
    cfg = ModelConfig.scene_segmenter(proto_stride=1, **SMALL)
    model = _random_detail(build_model(cfg)).eval()
    x = torch.rand(1, 3, H, W)
    with torch.no_grad():
        _, coeffs, protos = model.raw(x)
        pred, coarse, detail = model(x)
    k, d, nc = cfg.num_prototypes, cfg.detail_channels, cfg.num_classes
    assert coarse.shape == (1, k, H // 2, W // 2) and detail.shape == (1, d, H, W)
    assert pred.shape == (1, coeffs.shape[2], 4 + nc + k + d + 1)
    assert torch.equal(pred[0, :, 4 + nc:4 + nc + k], coeffs[0].T)
    some = torch.arange(0, coeffs.shape[2], 97)
    full = (coeffs[0].T[some] @ protos[0].reshape(k, -1)).reshape(-1, H, W)
    fast = instance_mask_logits(pred[0, some, 4 + nc:], coarse[0], detail[0])
    coarse_only = instance_mask_logits(pred[0, some, 4 + nc:4 + nc + k], coarse[0])
    coarse_only = coarse_only.repeat_interleave(2, dim=1).repeat_interleave(2, dim=2)
    scale = float(full.abs().max())
    assert float((full - coarse_only).abs().max()) > 0.1 * scale      # the detail really contributes
    assert torch.allclose(fast, full, atol=1e-5 * max(scale, 1.0), rtol=1e-4), float((fast - full).abs().max())


def test_a_stride_two_network_loaded_into_stride_one_keeps_its_masks_exactly():
    from cottonsim_perception.train import init_from_checkpoint
    torch.manual_seed(0)
    two = build_model(ModelConfig.scene_segmenter(proto_stride=2, **SMALL)).eval()
    torch.manual_seed(1)
    one = build_model(ModelConfig.scene_segmenter(proto_stride=1, **SMALL))
    with torch.no_grad():          # state of a trained stride-2 network: non-trivial BatchNorm statistics
        for m in two.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.normal_(0.0, 0.2)
                m.running_var.uniform_(0.5, 1.5)
    import tempfile, os
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "two.pt")
        save_checkpoint(path, two)
        init_from_checkpoint(one, path)
    one.eval()
    x = torch.rand(1, 3, H, W)
    with torch.no_grad():
        p2 = two.raw(x)[2]
        p1 = one.raw(x)[2]
        pred2, protos2 = two(x)
        pred1, coarse, detail = one(x)
    # bit-exact: nearest repetition of the stride-2 prototypes, plus a detail of exactly zero
    assert torch.equal(p1, p2.repeat_interleave(2, dim=2).repeat_interleave(2, dim=3))
    assert torch.equal(coarse, protos2)
    assert torch.equal(pred1[..., :pred2.shape[-1]], pred2)
    assert torch.all(pred1[..., pred2.shape[-1]:] == 0)
    # and the frame masks after postprocess are those of the stride-2 network's logits, repeated
    tf = LetterboxTransform.fit(W, H, W, H)
    cfg = PostprocessConfig(conf_threshold=float(pred2[0, :, 4:7].max()) - 1e-3)
    a = postprocess(pred2, 3, [tf], protos2, cfg)[0]
    b = postprocess(pred1, 3, [tf], coarse, cfg, detail)[0]
    assert len(a) == len(b) >= 1
    assert np.array_equal(a.boxes_xyxy, b.boxes_xyxy)
    # bilinear resize of a 2x2-repeated grid differs from that of the coarse grid only at edges
    assert (a.masks != b.masks).mean() < 0.05


def test_loss_at_full_resolution_trains_the_detail_path():
    torch.manual_seed(0)
    cfg = ModelConfig(task="seg", num_classes=1, class_names=("stem",), input_width=64, input_height=64,
                      width_multiple=0.0625, num_prototypes=4, proto_channels=8, proto_stride=1)
    model = build_model(cfg).train()
    img = torch.zeros(1, 3, 64, 64)
    img[:, 1, 8:56, 31:33] = 1.0                       # a 2 px wide green stem ...
    img[:, 1, 8:10, 16:48] = 1.0                       # ... with a 2 px twig across: box 32 x 48 px
    mask = img[:, 1].clone()
    targets = {"batch_idx": torch.tensor([0]), "classes": torch.tensor([0]),
               "boxes_xyxy": torch.tensor([[16.0, 8.0, 48.0, 56.0]]), "masks": mask}
    opt = torch.optim.AdamW(model.parameters(), lr=3e-3)
    loss_fn = YoloLoss(1, cfg.reg_max)
    start = model.head.proto.detail.conv.weight.detach().clone()
    for _ in range(5):
        loss, parts = loss_fn(model(img), targets)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert np.isfinite(parts["mask"])
    assert model.head.proto.detail_out.weight.abs().sum() > 0          # left zero -> learning
    assert not torch.equal(model.head.proto.detail.conv.weight, start)


def test_bad_stride_and_detail_settings_are_clear_errors():
    with pytest.raises(ValueError, match="proto_stride"):
        ModelConfig.scene_segmenter(proto_stride=3)
    for bad in (0, 65, 2.5, True):
        with pytest.raises(ValueError, match="detail_channels"):
            ModelConfig.scene_segmenter(proto_stride=1, detail_channels=bad)
    with pytest.raises(ValueError, match="needs the network input image"):
        Proto(8, 8, 4, stride=1)(torch.rand(1, 8, 4, 4))
    with pytest.raises(ValueError, match="stride 1 only"):
        Proto(8, 8, 4, stride=2).parts(torch.rand(1, 8, 4, 4), torch.rand(1, 3, 32, 32))
    with pytest.raises(ValueError, match="do not fit"):          # detail not at twice the prototype grid
        instance_mask_logits(torch.rand(2, 4 + 3 + 1), torch.rand(4, 8, 8), torch.rand(3, 8, 8))
    with pytest.raises(ValueError, match="do not fit"):          # too few coefficient columns
        instance_mask_logits(torch.rand(2, 4), torch.rand(4, 8, 8), torch.rand(3, 16, 16))


def test_crop_masks_by_slices_equals_the_full_size_box_product():
    # crop_masks zeroes by row / column slices (cheap at 320x256); it must keep exactly the pixels
    # whose centre is in the box, as the former full-size product did: random, empty, tied boxes
    from cottonsim_perception.nn.postprocess import crop_masks
    g = torch.Generator().manual_seed(0)
    for _ in range(100):
        n = int(torch.randint(0, 6, (1,), generator=g))
        masks = torch.rand(n, 37, 53, generator=g)
        boxes = torch.rand(n, 4, generator=g) * torch.tensor([70.0, 50, 70, 50]) - torch.tensor([10.0, 8, 10, 8])
        boxes[:, 2:] = torch.maximum(boxes[:, 2:], boxes[:, :2] - 1)          # some empty
        boxes[::3] = boxes[::3].round() * 0.5                                  # edges on pixel centres
        xs = torch.arange(53.0)[None, None, :] + 0.5
        ys = torch.arange(37.0)[None, :, None] + 0.5
        x1, y1, x2, y2 = (boxes[:, i, None, None] for i in range(4))
        expected = masks * ((xs >= x1) & (xs < x2) & (ys >= y1) & (ys < y2))
        assert torch.equal(crop_masks(masks, boxes), expected)


@pytest.mark.parametrize("with_detail", [False, True])
def test_box_soft_masks_equal_the_full_size_logits_cropped(with_detail):
    # postprocess computes the logits and sigmoids only inside each box's window; the values must be
    # those of the full-size path (instance_mask_logits, sigmoid, crop_masks) up to float rounding,
    # for boxes on odd and even rows / columns (the 2 x 2 repetition of the coarse logits), empty
    # boxes, boxes past the edges
    from cottonsim_perception.nn.postprocess import box_soft_masks, crop_masks
    g = torch.Generator().manual_seed(1)
    k, d, hp, wp = 5, 3, 9, 13
    for _ in range(60):
        n = int(torch.randint(0, 5, (1,), generator=g))
        protos = torch.randn(k, hp, wp, generator=g)
        detail = torch.randn(d, 2 * hp, 2 * wp, generator=g) if with_detail else None
        h, w = (2 * hp, 2 * wp) if with_detail else (hp, wp)
        extra = torch.randn(n, k + d + 1, generator=g) * 2.0
        boxes = torch.rand(n, 4, generator=g) * torch.tensor([w + 6.0, h + 6, w + 6, h + 6]) - 3.0
        boxes[:, 2:] = torch.maximum(boxes[:, 2:], boxes[:, :2] - 1)          # some empty
        expected = crop_masks(instance_mask_logits(extra if with_detail else extra[:, :k], protos, detail).sigmoid(),
                              boxes)
        got = box_soft_masks(extra if with_detail else extra[:, :k], protos, boxes, detail)
        assert got.shape == expected.shape
        assert torch.allclose(got, expected, atol=1e-6, rtol=0)
        assert torch.equal(got == 0, expected == 0)


def test_box_soft_masks_refuse_detail_that_does_not_fit():
    from cottonsim_perception.nn.postprocess import box_soft_masks
    with pytest.raises(ValueError, match="do not fit"):
        box_soft_masks(torch.rand(2, 8), torch.rand(4, 8, 8), torch.rand(2, 4), torch.rand(3, 8, 8))
