"""Shapes of the building blocks and of both networks, and checkpoint files."""
import pytest
import torch

from cottonsim_perception.nn.blocks import (C2f, SPPF, Backbone, Bottleneck, Conv, PANNeck, fuse_model,
                                            scale_depth, scale_width)
from cottonsim_perception.nn.models import (ModelConfig, YoloDetector, YoloSegmenter, build_model,
                                            count_parameters, load_model, save_checkpoint)


def test_scaling_rules():
    # YOLOv8n: width 0.25 -> 16, 32, 64, 128, 256; depth 0.33: 3 -> 1, 6 -> 2
    assert [scale_width(c, 0.25) for c in (64, 128, 256, 512, 1024)] == [16, 32, 64, 128, 256]
    assert scale_depth(3, 0.33) == 1 and scale_depth(6, 0.33) == 2 and scale_depth(1, 0.33) == 1
    assert scale_width(64, 0.01) == 8      # never below one group of 8


def test_block_shapes():
    x = torch.rand(2, 8, 32, 40)
    assert Conv(8, 16, 3, 2)(x).shape == (2, 16, 16, 20)
    assert Bottleneck(8, 8)(x).shape == x.shape
    assert C2f(8, 24, n=2, shortcut=True)(x).shape == (2, 24, 32, 40)
    assert SPPF(8, 12)(x).shape == (2, 12, 32, 40)


def test_backbone_and_neck_strides():
    bb = Backbone(0.125, 0.33)
    neck = PANNeck(bb.out_channels, 0.33)
    feats = neck(bb(torch.rand(1, 3, 64, 96)))
    assert [tuple(f.shape[2:]) for f in feats] == [(8, 12), (4, 6), (2, 3)]
    assert [f.shape[1] for f in feats] == list(bb.out_channels) == [32, 64, 128]


def test_detector_shapes_train_and_eval():
    m = YoloDetector(num_classes=2, width_multiple=0.0625, depth_multiple=0.33)
    x = torch.rand(2, 3, 64, 96)
    maps = m.train()(x)
    assert [tuple(t.shape) for t in maps] == [(2, 66, 8, 12), (2, 66, 4, 6), (2, 66, 2, 3)]
    out = m.eval()(x)
    anchors = 8 * 12 + 4 * 6 + 2 * 3
    assert out.shape == (2, anchors, 4 + 2)
    assert torch.all((out[..., 4:] >= 0) & (out[..., 4:] <= 1))
    assert torch.all(out[..., 2] >= out[..., 0]) and torch.all(out[..., 3] >= out[..., 1])


def test_segmenter_shapes_train_and_eval():
    m = YoloSegmenter(num_classes=3, num_prototypes=8, width_multiple=0.0625)
    x = torch.rand(1, 3, 64, 96)
    maps, coeffs, protos = m.train()(x)
    anchors = 8 * 12 + 4 * 6 + 2 * 3
    assert maps[0].shape == (1, 64 + 3, 8, 12)
    assert coeffs.shape == (1, 8, anchors)
    assert protos.shape == (1, 8, 16, 24)          # stride 4
    pred, protos_eval = m.eval()(x)
    assert pred.shape == (1, anchors, 4 + 3 + 8) and protos_eval.shape == protos.shape


def test_bad_input_shape_is_a_clear_error():
    m = YoloDetector(width_multiple=0.0625).eval()
    with pytest.raises(ValueError, match="multiples of 32"):
        m(torch.rand(1, 3, 50, 64))
    with pytest.raises(ValueError, match="B, 3, H, W"):
        m(torch.rand(3, 64, 64))


def test_fused_model_gives_the_same_output():
    m = YoloSegmenter(width_multiple=0.0625)
    # give the BatchNorms non-trivial statistics
    m.train()
    with torch.no_grad():
        for _ in range(3):
            m(torch.rand(2, 3, 64, 64))
    m.eval()
    x = torch.rand(1, 3, 64, 64)
    with torch.no_grad():
        ref_pred, ref_protos = m(x)
        fuse_model(m)
        pred, protos = m(x)
    assert torch.allclose(pred, ref_pred, atol=1e-3, rtol=1e-3)
    assert torch.allclose(protos, ref_protos, atol=1e-4, rtol=1e-3)


def test_config_validation_names_the_parameter():
    with pytest.raises(ValueError, match="input_width"):
        ModelConfig(input_width=100)
    with pytest.raises(ValueError, match="task"):
        ModelConfig(task="cls")
    with pytest.raises(ValueError, match="class_names"):
        ModelConfig(num_classes=2)
    assert ModelConfig.from_dict(ModelConfig.boll_detector().to_dict()) == ModelConfig.boll_detector()


def test_checkpoint_round_trip(tmp_path):
    cfg = ModelConfig.scene_segmenter(width_multiple=0.0625, input_width=64, input_height=64)
    m = build_model(cfg).eval()
    path = str(tmp_path / "w.pt")
    save_checkpoint(path, m, {"epochs": 3, "data": "/x", "seed": 7, "metrics": {"val_loss": [1.0, 0.5]}})
    # the file is weights_only-safe
    raw = torch.load(path, weights_only=True)
    assert raw["model_config"]["task"] == "seg" and raw["train"]["seed"] == 7
    loaded = load_model(path)
    assert loaded.config == cfg and not loaded.training
    assert loaded.train_meta["metrics"]["val_loss"] == [1.0, 0.5]
    x = torch.rand(1, 3, 64, 64)
    with torch.no_grad():
        assert torch.equal(loaded(x)[0], m(x)[0])
    assert count_parameters(loaded) == count_parameters(m)


def test_missing_or_wrong_weights_raise_clear_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        load_model(str(tmp_path / "nope.pt"))
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="not a readable"):
        load_model(str(junk))
    other = tmp_path / "other.pt"
    torch.save({"state_dict": {}}, str(other))
    with pytest.raises(ValueError, match="not a CottonSim"):
        load_model(str(other))
    # weights that do not fit the config
    m = build_model(ModelConfig.boll_detector(width_multiple=0.0625))
    path = str(tmp_path / "w.pt")
    save_checkpoint(path, m)
    ck = torch.load(path, weights_only=True)
    ck["model_config"]["width_multiple"] = 0.125
    torch.save(ck, path)
    with pytest.raises(ValueError, match="do not match"):
        load_model(path)


def test_proto_stride_two_gives_masks_at_half_the_input():
    from cottonsim_perception.nn.models import ModelConfig, build_model
    cfg = ModelConfig.scene_segmenter(width_multiple=0.0625, input_width=128, input_height=96, proto_stride=2)
    model = build_model(cfg).eval()
    with torch.no_grad():
        pred, protos = model(torch.rand(1, 3, 96, 128))
    assert protos.shape == (1, cfg.num_prototypes, 48, 64)
    four = build_model(ModelConfig.scene_segmenter(width_multiple=0.0625, input_width=128, input_height=96)).eval()
    with torch.no_grad():
        assert four(torch.rand(1, 3, 96, 128))[1].shape[-2:] == (24, 32)
    with pytest.raises(ValueError, match="proto_stride"):
        ModelConfig.scene_segmenter(proto_stride=8)
