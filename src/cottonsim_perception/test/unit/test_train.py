"""Training loop: fine-tuning from a checkpoint and mixed datasets (tiny CPU runs)."""
import os

import cv2
import numpy as np
import pytest
import torch

from cottonsim_perception.data import yolo_format as yf
from cottonsim_perception.nn.models import load_checkpoint
from cottonsim_perception.train import TrainConfig, train


def _dataset(root, names, seed):
    """train/valid splits of 64x64 images with one bright box each (class 0)."""
    rng = np.random.default_rng(seed)
    for split, n in (("train", 3), ("valid", 1)):
        os.makedirs(os.path.join(root, split, "images"))
        for i in range(n):
            img = np.full((64, 64, 3), 40, np.uint8)
            x, y = rng.integers(4, 40, size=2)
            img[y:y + 16, x:x + 16] = 230
            cv2.imwrite(os.path.join(root, split, "images", f"{i}.png"), img)
            box = np.array([(x + 8) / 64, (y + 8) / 64, 16 / 64, 16 / 64])
            yf.write_label_file(os.path.join(root, split, "labels", f"{i}.txt"),
                                [yf.LabelInstance(0, box)], "det")
    with open(os.path.join(root, "data.yaml"), "w") as fh:
        fh.write(f"path: {root}\ntrain: train/images\nval: valid/images\nnames: {list(names)}\n")


def _cfg(tmp_path, out, **kw):
    base = dict(task="det", data_dir=str(tmp_path / "a"), out_dir=str(tmp_path / out), epochs=1, batch=2,
                imgsz=(64, 64), width_multiple=0.0625, warmup_iters=0)
    base.update(kw)
    return TrainConfig(**base)


def _weights(path):
    ckpt = load_checkpoint(path)
    return {k: v for k, v in ckpt["state_dict"].items() if "running" not in k and "num_batches" not in k}


def test_fine_tuning_starts_from_the_given_weights_and_mixes_datasets(tmp_path):
    _dataset(str(tmp_path / "a"), ["cotton boll"], 0)
    _dataset(str(tmp_path / "b"), ["cotton boll"], 1)
    log = []
    train(_cfg(tmp_path, "first", seed=1), log=log.append)
    start = str(tmp_path / "first" / "last.pt")
    # a near-zero learning rate: the fine-tuned weights stay where they started ...
    meta = train(_cfg(tmp_path, "ft", seed=2, lr=1e-9, init_weights=start,
                      extra_data_dirs=(str(tmp_path / "b"),)), log=log.append)
    assert meta["extra_data"] == [str(tmp_path / "b")]
    assert any("initialised from" in line for line in log)
    w0, w1 = _weights(start), _weights(str(tmp_path / "ft" / "last.pt"))
    assert max(float((w0[k] - w1[k]).abs().max()) for k in w0) < 1e-5
    # ... while a run of another seed without them ends elsewhere
    train(_cfg(tmp_path, "scratch", seed=2, lr=1e-9), log=log.append)
    w2 = _weights(str(tmp_path / "scratch" / "last.pt"))
    assert max(float((w0[k] - w2[k]).abs().max()) for k in w0) > 1e-3


def test_an_extra_dataset_without_a_validation_split_only_trains(tmp_path):
    import shutil

    from cottonsim_perception.data.yolo_dataset import YoloDataset
    from cottonsim_perception.train import _datasets

    _dataset(str(tmp_path / "a"), ["cotton boll"], 0)
    _dataset(str(tmp_path / "b"), ["cotton boll"], 1)
    shutil.rmtree(str(tmp_path / "b" / "valid"))          # data.yaml still names it
    log = []
    train_set, val_set, _ = _datasets(_cfg(tmp_path, "x", extra_data_dirs=(str(tmp_path / "b"),)), 64, 64,
                                      YoloDataset, log.append)
    assert (len(train_set), len(val_set)) == (6, 1)
    assert any("no validation split" in line for line in log)
    # an empty one is the same; the main dataset must have one
    os.makedirs(str(tmp_path / "b" / "valid" / "images"))
    _, val_set, _ = _datasets(_cfg(tmp_path, "x", extra_data_dirs=(str(tmp_path / "b"),)), 64, 64,
                              YoloDataset, log.append)
    assert len(val_set) == 1
    with pytest.raises(yf.LabelFormatError, match="valid"):
        _datasets(_cfg(tmp_path, "x", data_dir=str(tmp_path / "b")), 64, 64, YoloDataset, log.append)


def test_fine_tuning_and_mixing_errors_are_clear(tmp_path):
    _dataset(str(tmp_path / "a"), ["cotton boll"], 0)
    _dataset(str(tmp_path / "c"), ["weed"], 2)
    with pytest.raises(ValueError, match="init_weights"):
        _cfg(tmp_path, "x", init_weights=str(tmp_path / "missing.pt"))
    with pytest.raises(ValueError, match="extra_data_dirs"):
        _cfg(tmp_path, "x", extra_data_dirs=(str(tmp_path / "nope"),))
    with pytest.raises(ValueError, match="mosaic_prob"):
        _cfg(tmp_path, "x", mosaic_prob=2.0)
    with pytest.raises(ValueError, match="class names"):
        train(_cfg(tmp_path, "x", extra_data_dirs=(str(tmp_path / "c"),)), log=lambda s: None)
    train(_cfg(tmp_path, "first"), log=lambda s: None)
    with pytest.raises(ValueError, match="model_config differs"):
        train(_cfg(tmp_path, "y", width_multiple=0.125, init_weights=str(tmp_path / "first" / "last.pt")),
              log=lambda s: None)


def test_fine_tuning_at_another_input_size_starts_from_the_same_weights(tmp_path):
    from cottonsim_perception.nn.models import ModelConfig, build_model, save_checkpoint
    from cottonsim_perception.train import init_from_checkpoint

    torch.manual_seed(0)
    small = build_model(ModelConfig.boll_detector(width_multiple=0.0625, input_width=128, input_height=96)).eval()
    path = str(tmp_path / "small.pt")
    save_checkpoint(path, small)
    torch.manual_seed(1)
    large = build_model(ModelConfig.boll_detector(width_multiple=0.0625, input_width=160, input_height=128))
    line = init_from_checkpoint(large, path)
    assert "trained at input 128x96, now 160x128" in line
    assert all(torch.equal(v, large.state_dict()[k]) for k, v in small.state_dict().items())
    assert (large.config.input_width, large.config.input_height) == (160, 128)      # the run's own size
    with pytest.raises(ValueError, match="model_config differs"):     # another width still refuses
        init_from_checkpoint(build_model(ModelConfig.boll_detector(width_multiple=0.125)), path)


def test_fine_tuning_to_finer_prototypes_keeps_every_matching_tensor(tmp_path):
    from cottonsim_perception.nn.models import ModelConfig, build_model, save_checkpoint
    from cottonsim_perception.train import init_from_checkpoint

    torch.manual_seed(0)
    coarse = build_model(ModelConfig.scene_segmenter(width_multiple=0.0625)).eval()
    path = str(tmp_path / "coarse.pt")
    save_checkpoint(path, coarse)
    torch.manual_seed(1)
    fine = build_model(ModelConfig.scene_segmenter(width_multiple=0.0625, proto_stride=2))
    line = init_from_checkpoint(fine, path)
    old, new = coarse.state_dict(), fine.state_dict()
    same = [k for k in new if k in old and old[k].shape == new[k].shape]
    assert all(torch.equal(old[k], new[k]) for k in same)
    fresh = [k for k in new if k not in same]
    # only the new upsampling stage starts fresh, as a nearest-neighbour copy: the finer network
    # first reproduces the coarse one's prototypes, each pixel repeated 2 x 2
    assert sorted(fresh) == ["head.proto.upsample2.bias", "head.proto.upsample2.weight"]
    assert "2 new" in line
    x = torch.rand(1, 3, 256, 320)
    with torch.no_grad():
        p4 = coarse.eval()(x)[1]
        p2 = fine.eval()(x)[1]
    assert p2.shape[-2:] == (128, 160)
    assert torch.allclose(p2, p4.repeat_interleave(2, dim=2).repeat_interleave(2, dim=3), atol=1e-5)
    with pytest.raises(ValueError, match="model_config differs"):
        init_from_checkpoint(build_model(ModelConfig.scene_segmenter(width_multiple=0.125, proto_stride=2)), path)
    # and on to stride 1: only the detail path is new (the stride-2 stage is loaded), masks kept exactly
    path2 = str(tmp_path / "fine.pt")
    save_checkpoint(path2, fine.eval())
    torch.manual_seed(2)
    full = build_model(ModelConfig.scene_segmenter(width_multiple=0.0625, proto_stride=1, detail_channels=4))
    line = init_from_checkpoint(full, path2)
    own = full.state_dict()
    fresh = sorted(k for k in own if k not in fine.state_dict())
    assert fresh and all(k.startswith(("head.proto.detail.", "head.proto.detail_out.")) for k in fresh)
    assert f"{len(fresh)} new" in line and "proto_stride 2 -> 1" in line
    with torch.no_grad():
        p1 = full.eval().raw(x)[2]
        p2 = fine.raw(x)[2]
    assert torch.equal(p1, p2.repeat_interleave(2, dim=2).repeat_interleave(2, dim=3))


def test_train_config_accepts_stride_one_for_the_segmenter_only(tmp_path):
    _dataset(str(tmp_path / "a"), ["box"], 0)
    assert _cfg(tmp_path, "s", task="seg", proto_stride=1).proto_stride == 1
    for task, stride in (("det", 1), ("seg", 3)):
        with pytest.raises(ValueError, match="proto_stride"):
            _cfg(tmp_path, "s", task=task, proto_stride=stride)


def test_train_config_takes_a_mask_dice_weight_for_the_segmenter_only(tmp_path):
    _dataset(str(tmp_path / "a"), ["box"], 0)
    assert _cfg(tmp_path, "s", task="seg", mask_dice_weight=0.5).mask_dice_weight == 0.5
    with pytest.raises(ValueError, match="mask_dice_weight is for task 'seg'"):
        _cfg(tmp_path, "s", task="det", mask_dice_weight=0.5)
    for bad in (-1.0, float("nan"), float("inf"), True, "1"):
        with pytest.raises(ValueError, match="mask_dice_weight"):
            _cfg(tmp_path, "s", task="seg", mask_dice_weight=bad)


def test_worker_processes_load_the_same_batches_as_the_training_process(tmp_path):
    # the augmentation of item i in epoch e does not depend on who loads it: two workers train
    # the same weights as loading in-process (seeded run, deterministic CPU kernels)
    _dataset(str(tmp_path / "a"), ["cotton boll"], 0)
    train(_cfg(tmp_path, "inproc", seed=3, epochs=2, mosaic_prob=0.5), log=lambda s: None)
    train(_cfg(tmp_path, "workers", seed=3, epochs=2, mosaic_prob=0.5, workers=2), log=lambda s: None)
    w0, w1 = _weights(str(tmp_path / "inproc" / "last.pt")), _weights(str(tmp_path / "workers" / "last.pt"))
    assert max(float((w0[k] - w1[k]).abs().max()) for k in w0) < 1e-6


def test_device_and_workers_are_checked(tmp_path):
    _dataset(str(tmp_path / "a"), ["cotton boll"], 0)
    with pytest.raises(ValueError, match="workers"):
        _cfg(tmp_path, "x", workers=-1)
    with pytest.raises(ValueError, match="device"):
        _cfg(tmp_path, "x", device="not-a-device")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="no CUDA device"):
            _cfg(tmp_path, "x", device="cuda")
