"""Tests of the YOLO torch Dataset: shapes, letterbox mapping, label-consistent augmentation."""
import os

import cv2
import numpy as np
import pytest
import torch

from cottonsim_perception.data import yolo_format as yf
from cottonsim_perception.data.yolo_dataset import AugmentConfig, YoloDataset, collate

W0, H0 = 80, 40
BOX = (10, 10, 30, 20)            # x1, y1, x2, y2 [px] of the white object


def _make(root, task):
    """One black 80 x 40 image with a white rectangle labelled as class 1."""
    img = np.zeros((H0, W0, 3), np.uint8)
    x1, y1, x2, y2 = BOX
    img[y1:y2, x1:x2] = 255
    os.makedirs(os.path.join(root, "train", "images"))
    cv2.imwrite(os.path.join(root, "train", "images", "a.png"), img)
    poly = np.array([[x1, y1], [x2, y1], [x2, y2], [x1, y2]], float) / [W0, H0]
    inst = yf.LabelInstance(1, yf.polygon_bbox_cxcywh(poly), poly)
    yf.write_label_file(os.path.join(root, "train", "labels", "a.txt"), [inst], task)
    # a background image without a label file
    cv2.imwrite(os.path.join(root, "train", "images", "b.png"), np.zeros((H0, W0, 3), np.uint8))


@pytest.mark.parametrize("task", ["seg", "det"])
def test_item_shapes_and_letterbox_mapping(tmp_path, task):
    _make(str(tmp_path), task)
    ds = YoloDataset(str(tmp_path), "train", task, imgsz=(64, 64), class_names=("a", "b"))
    assert len(ds) == 2
    img, t = ds[0]
    assert img.shape == (3, 64, 64) and img.dtype == torch.float32
    assert 0.0 <= float(img.min()) and float(img.max()) <= 1.0
    # scale 64/80 = 0.8 -> content 64 x 32, padded 16 px top: box (8, 24, 24, 32)
    np.testing.assert_allclose(t["boxes_xyxy"].numpy(), [[8, 24, 24, 32]], atol=1.0)
    assert t["classes"].tolist() == [1]
    if task == "seg":
        assert t["masks"].shape == (1, 64, 64) and t["masks"].dtype == torch.uint8
        assert int(t["masks"].sum()) == pytest.approx(16 * 8, abs=24)
    else:
        assert "masks" not in t
    _, t_bg = ds[1]
    assert t_bg["boxes_xyxy"].shape == (0, 4)
    images, batch = collate([ds[0], ds[1]])
    assert images.shape == (2, 3, 64, 64)
    assert batch["batch_idx"].tolist() == [0] and batch["boxes_xyxy"].shape == (1, 4)
    if task == "seg":
        assert batch["masks"].shape == (1, 64, 64)


@pytest.mark.parametrize("task", ["seg", "det"])
def test_flip_moves_box_to_mirrored_position(tmp_path, task):
    _make(str(tmp_path), task)
    cfg = AugmentConfig(flip_lr_prob=1.0, hsv_h=0, hsv_s=0, hsv_v=0, scale=0, translate=0)
    ds = YoloDataset(str(tmp_path), "train", task, imgsz=(W0, H0), augment=True,
                     class_names=("a", "b"), augment_config=cfg)
    img, t = ds[0]
    # Mirrored: x' = W - x -> (80 - 30, 10, 80 - 10, 20)
    np.testing.assert_allclose(t["boxes_xyxy"].numpy(), [[50, 10, 70, 20]], atol=0.5)
    white = img[0].numpy() > 0.5
    assert white[10:20, 50:70].all() and white.sum() == 200
    if task == "seg":
        assert (t["masks"][0].numpy().astype(bool) == white).all()


@pytest.mark.parametrize("task", ["seg", "det"])
def test_random_geometry_keeps_boxes_on_the_object(tmp_path, task):
    _make(str(tmp_path), task)
    cfg = AugmentConfig(scale=0.2, translate=0.1, rotation_deg=13.0, min_box_px=1.0)
    ds = YoloDataset(str(tmp_path), "train", task, imgsz=(96, 64), augment=True, seed=3,
                     class_names=("a", "b"), augment_config=cfg)
    for epoch in range(6):
        ds.set_epoch(epoch)
        img, t = ds[0]
        assert t["boxes_xyxy"].shape == (1, 4)
        x1, y1, x2, y2 = t["boxes_xyxy"][0].tolist()
        # The object is the bright region (HSV jitter keeps white bright).
        ys, xs = np.nonzero(img.numpy().mean(axis=0) > 0.6)
        assert xs.size > 50
        assert xs.min() >= x1 - 1.5 and xs.max() + 1 <= x2 + 1.5
        assert ys.min() >= y1 - 1.5 and ys.max() + 1 <= y2 + 1.5
        if task == "seg":
            m = t["masks"][0].numpy().astype(bool)
            bright = img.numpy().mean(axis=0) > 0.6
            overlap = (m & bright).sum() / max((m | bright).sum(), 1)
            assert overlap > 0.8


def test_augmentation_is_reproducible_per_seed_and_epoch(tmp_path):
    _make(str(tmp_path), "det")
    a = YoloDataset(str(tmp_path), "train", "det", imgsz=(64, 64), augment=True, seed=1,
                    class_names=("a", "b"))
    b = YoloDataset(str(tmp_path), "train", "det", imgsz=(64, 64), augment=True, seed=1,
                    class_names=("a", "b"))
    assert torch.equal(a[0][0], b[0][0])
    b.set_epoch(1)
    assert not torch.equal(a[0][0], b[0][0])


def test_bad_arguments_and_labels(tmp_path):
    _make(str(tmp_path), "det")
    with pytest.raises(ValueError, match="imgsz"):
        YoloDataset(str(tmp_path), "train", "det", imgsz=(0, 64))
    with pytest.raises(ValueError, match="task"):
        YoloDataset(str(tmp_path), "train", "pose")
    with pytest.raises(ValueError, match="AugmentConfig.scale"):
        AugmentConfig(scale=1.5)
    # class id 1 with a single class name -> error naming file and line
    with pytest.raises(yf.LabelFormatError, match=r"a\.txt:1"):
        YoloDataset(str(tmp_path), "train", "det", class_names=("only",))


@pytest.mark.parametrize("task", ["seg", "det"])
def test_mosaic_labels_follow_the_pasted_objects(tmp_path, task):
    _make(str(tmp_path), task)
    cfg = AugmentConfig(hsv_h=0, hsv_s=0, hsv_v=0, scale=0.1, translate=0.2, mosaic_prob=1.0,
                        mosaic_min_visible=0.0, min_box_px=0.0)
    ds = YoloDataset(str(tmp_path), "train", task, imgsz=(W0, H0), augment=True, seed=5,
                     class_names=("a", "b"), augment_config=cfg)
    n_boxes = 0
    for epoch in range(8):
        ds.set_epoch(epoch)
        img, t = ds[0]
        bright = img.numpy().mean(axis=0) > 0.5
        covered = np.zeros_like(bright)
        for bx in t["boxes_xyxy"].numpy():
            assert bx[2] > bx[0] and bx[3] > bx[1]
            x1, y1 = np.floor(bx[:2]).astype(int)
            x2, y2 = np.ceil(bx[2:]).astype(int)
            if (x2 - x1) * (y2 - y1) >= 4:                   # a box sits on a pasted object
                assert bright[y1:y2, x1:x2].mean() > 0.5
            covered[y1:y2, x1:x2] = True
        # every visible object has a box (up to its 1-px blurred rim; solid pixels only)
        covered = cv2.dilate(covered.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        solid = img.numpy().mean(axis=0) > 0.9
        assert (solid & ~covered).sum() == 0
        n_boxes += len(t["boxes_xyxy"])
        if task == "seg":
            union = t["masks"].numpy().astype(bool).any(axis=0) if len(t["masks"]) else covered & False
            near = cv2.dilate(bright.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
            assert not (solid & ~union).any() and not (union & ~near).any()
    assert n_boxes >= 4                                       # objects did get pasted


def test_mosaic_probability_is_validated():
    with pytest.raises(ValueError, match="mosaic_prob"):
        AugmentConfig(mosaic_prob=1.5)


def test_ignore_boxes_travel_with_the_image_and_stay_out_of_the_labels(tmp_path):
    root = str(tmp_path)
    _make(root, "det")
    # a don't-care box at (50, 5)-(70, 15) of image a
    yf.write_label_file(os.path.join(root, "train", "ignore", "a.txt"),
                        [yf.LabelInstance(0, np.array([60 / W0, 10 / H0, 20 / W0, 10 / H0]))], "det")
    ds = YoloDataset(root, "train", "det", imgsz=(W0, H0), class_names=("a", "b"))
    _, t = ds[0]
    assert t["classes"].tolist() == [1]
    np.testing.assert_allclose(t["ignore_boxes_xyxy"].numpy(), [[50, 5, 70, 15]], atol=0.5)
    cfg = AugmentConfig(flip_lr_prob=1.0, hsv_h=0, hsv_s=0, hsv_v=0, scale=0, translate=0)
    flipped = YoloDataset(root, "train", "det", imgsz=(W0, H0), augment=True, class_names=("a", "b"),
                          augment_config=cfg)
    _, tf = flipped[0]
    np.testing.assert_allclose(tf["ignore_boxes_xyxy"].numpy(), [[10, 5, 30, 15]], atol=0.5)
    _, batch = collate([ds[1], ds[0]])
    assert batch["ignore_batch_idx"].tolist() == [1] and batch["ignore_boxes_xyxy"].shape == (1, 4)
    assert batch["batch_idx"].tolist() == [1]
