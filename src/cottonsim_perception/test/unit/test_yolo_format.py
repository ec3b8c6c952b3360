"""Tests of the YOLO label / layout reader and the polygon <-> mask conversions."""
import os
import re

import cv2
import numpy as np
import pytest

from cottonsim_perception.data import yolo_format as yf


def test_parse_detection_line_gives_box_in_pixels():
    inst = yf.parse_label_line("0 0.5 0.25 0.2 0.1", "det", num_classes=1)
    assert inst.class_id == 0 and inst.polygon is None
    # 200 x 100 image: centre (100, 25), size 40 x 10 -> (80, 20, 120, 30)
    np.testing.assert_allclose(inst.box_xyxy_px(200, 100), [80, 20, 120, 30])


def test_parse_polygon_line_and_bbox():
    inst = yf.parse_label_line("2 0.1 0.2 0.5 0.2 0.3 0.6", "seg", num_classes=3)
    assert inst.class_id == 2
    np.testing.assert_allclose(inst.polygon, [[0.1, 0.2], [0.5, 0.2], [0.3, 0.6]])
    np.testing.assert_allclose(inst.box_cxcywh, [0.3, 0.4, 0.4, 0.4])


def test_polygon_in_detection_dataset_is_read_as_its_box():
    inst = yf.parse_label_line("0 0.1 0.1 0.3 0.1 0.3 0.5", "det")
    np.testing.assert_allclose(inst.box_xyxy_px(10, 10), [1, 1, 3, 5])


def test_blank_line_is_none_and_small_overshoot_clipped():
    assert yf.parse_label_line("   ", "seg") is None
    inst = yf.parse_label_line("0 -0.005 0.0 1.004 0.0 0.5 1.0", "seg")
    assert inst.polygon.min() == 0.0 and inst.polygon.max() == 1.0


@pytest.mark.parametrize("line,task,fragment", [
    ("3 0.1 0.1 0.2 0.2 0.3 0.3", "seg", "class id 3 out of range"),
    ("-1 0.1 0.1 0.2 0.2", "det", "non-negative integer"),
    ("1.5 0.1 0.1 0.2 0.2", "det", "non-negative integer"),
    ("cat 0.1 0.1 0.2 0.2", "det", "not a number"),
    ("0 0.1 0.1 0.2 0.2 0.3", "seg", "odd number"),
    ("0 0.1 0.1 0.2 0.2 0.3 0.3 0.4", "seg", "odd number"),
    ("0 0.1 0.1", "det", "expected 4 box values"),
    ("0 0.5 0.5 0.2 0.2", "seg", "needs a polygon"),
    ("0 0.1 0.1 1.2 0.2 0.3 0.3", "seg", "outside [0, 1]"),
    ("0 0.1 -0.05 0.2 0.2 0.3 0.3", "seg", "outside [0, 1]"),
    ("0 nan 0.1 0.2 0.2 0.3 0.3", "seg", "NaN"),
    ("0 0.5 0.5 0.0 0.2", "det", "width and height"),
    ("0 0.5 0.5 abc 0.2", "det", "non-numeric"),
])
def test_malformed_lines_name_file_and_line(line, task, fragment):
    with pytest.raises(yf.LabelFormatError) as err:
        yf.parse_label_line(line, task, num_classes=3, source="lbl.txt", line_number=7)
    msg = str(err.value)
    assert "lbl.txt:7" in msg and fragment in msg


def test_read_label_file_reports_the_bad_line(tmp_path):
    p = tmp_path / "a.txt"
    p.write_text("0 0.5 0.5 0.1 0.1\n\n0 0.5 0.5 0.1\n")
    with pytest.raises(yf.LabelFormatError, match=r"a\.txt:3"):
        yf.read_label_file(str(p), "det", 1)
    assert yf.read_label_file(str(tmp_path / "missing.txt"), "det") == []


def test_write_then_read_round_trip(tmp_path):
    poly = np.array([[0.1, 0.2], [0.9, 0.25], [0.5, 0.8]])
    insts = [yf.LabelInstance(1, yf.polygon_bbox_cxcywh(poly), poly)]
    path = str(tmp_path / "sub" / "x.txt")
    yf.write_label_file(path, insts, "seg")
    back = yf.read_label_file(path, "seg", 3)
    assert len(back) == 1 and back[0].class_id == 1
    np.testing.assert_allclose(back[0].polygon, poly, atol=1e-6)
    yf.write_label_file(path, insts, "det")
    back = yf.read_label_file(path, "det", 3)
    np.testing.assert_allclose(back[0].box_cxcywh, [0.5, 0.5, 0.8, 0.6], atol=1e-6)


def test_polygon_to_mask_full_image_and_rectangle():
    assert yf.polygon_to_mask(np.array([[0, 0], [30, 0], [30, 20], [0, 20]]), 20, 30).all()
    # pixel-edge rectangle [5, 17] x [3, 9] covers columns 5..16, rows 3..8
    m = yf.polygon_to_mask(np.array([[5, 3], [17, 3], [17, 9], [5, 9]]), 20, 30)
    expected = np.zeros((20, 30), bool)
    expected[3:9, 5:17] = True
    assert (m == expected).all()
    # a right triangle with legs of 10 px: centres (c + .5, r + .5) with c + r + 1 <= 10
    # strictly inside the hypotenuse x + y < 10 (on it: excluded as a right edge)
    tri = yf.polygon_to_mask(np.array([[0, 0], [10, 0], [0, 10]]), 12, 12)
    rr, cc = np.mgrid[0:12, 0:12]
    assert (tri == (rr + cc + 1 < 10)).all()
    # polygons partly outside the image are clipped, not wrapped
    out = yf.polygon_to_mask(np.array([[-5, -5], [3, -5], [3, 2], [-5, 2]]), 6, 6)
    assert out.sum() == 6 and out[:2, :3].all()
    assert not yf.polygon_to_mask(np.array([[0, 0], [1, 1]]), 5, 5).any()  # < 3 points


def test_mask_polygon_round_trip_exact_on_random_blobs():
    rng = np.random.default_rng(5)
    for _ in range(20):
        m = np.zeros((40, 50), np.uint8)
        for _k in range(3):
            cv2.ellipse(m, (int(rng.integers(5, 45)), int(rng.integers(5, 35))),
                        (int(rng.integers(2, 12)), int(rng.integers(2, 12))),
                        float(rng.uniform(0, 180)), 0, 360, 1, -1)
        m = m.astype(bool) & (rng.random(m.shape) > 0.05)   # ragged edges, diagonal links
        back = np.zeros_like(m)
        for poly in yf.mask_to_polygons(m, epsilon_px=0, min_area_px=0):
            back |= yf.polygon_to_mask(poly, 40, 50)
        # holes are not represented: compare with the hole-filled mask
        cs, _ = cv2.findContours(m.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        filled = np.zeros(m.shape, np.uint8)
        cv2.drawContours(filled, cs, -1, 1, -1)
        assert (back == filled.astype(bool)).all()


def test_mask_polygon_round_trip_exact_without_simplification():
    disk = np.zeros((60, 70), np.uint8)
    cv2.circle(disk, (30, 28), 19, 1, -1)
    disk = disk.astype(bool)
    polys = yf.mask_to_polygons(disk, epsilon_px=0)
    assert len(polys) == 1
    assert (yf.polygon_to_mask(polys[0], 60, 70) == disk).all()
    # Simplified polygons stay close: few vertices, error only along the rim.
    simple = yf.mask_to_polygons(disk, epsilon_px=1.0)[0]
    back = yf.polygon_to_mask(simple, 60, 70)
    assert len(simple) < len(polys[0])
    assert (back != disk).sum() < 0.05 * disk.sum()


def test_mask_to_polygons_splits_regions_and_drops_specks():
    m = np.zeros((20, 40), bool)
    m[2:8, 2:10] = True
    m[10:18, 20:35] = True
    m[0, 39] = True  # a one-pixel speck
    polys = yf.mask_to_polygons(m)
    assert len(polys) == 2
    boxes = sorted(tuple(yf.polygon_bbox_xyxy(p)) for p in polys)
    # region cols 2..9, rows 2..7: contour a quarter pixel inside its edges
    np.testing.assert_allclose(boxes[0], (2.25, 2.25, 9.75, 7.75))
    assert yf.mask_to_polygons(np.zeros((5, 5), bool)) == []


def _touch(path):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    cv2.imwrite(path, np.zeros((8, 8, 3), np.uint8))


def test_find_pairs_in_roboflow_layout(tmp_path):
    root = str(tmp_path)
    _touch(os.path.join(root, "valid", "images", "b.jpg"))
    _touch(os.path.join(root, "valid", "images", "a.png"))
    pairs = yf.list_pairs(root, "val")  # 'val' finds 'valid'
    assert [os.path.basename(p.image_path) for p in pairs] == ["a.png", "b.jpg"]
    assert pairs[0].label_path == os.path.join(root, "valid", "labels", "a.txt")


def test_find_pairs_in_ultralytics_layout_and_data_yaml(tmp_path):
    root = str(tmp_path)
    _touch(os.path.join(root, "images", "val", "c.jpg"))
    pairs = yf.list_pairs(root, "valid")
    assert pairs[0].label_path == os.path.join(root, "labels", "val", "c.txt")
    _touch(os.path.join(root, "other", "images", "d.jpg"))
    yf.write_data_yaml(os.path.join(root, "data.yaml"),
                       yf.DataYaml(path=".", train="other/images", val="images/val", names=("x", "y")))
    assert [os.path.basename(p.image_path) for p in yf.list_pairs(root, "train")] == ["d.jpg"]
    assert yf.class_names_for(root, "det") == ("x", "y")
    assert yf.read_data_yaml(os.path.join(root, "data.yaml")).names == ("x", "y")


def test_layout_errors_are_clear(tmp_path):
    with pytest.raises(yf.LabelFormatError, match="does not exist"):
        yf.list_pairs(str(tmp_path / "nope"), "test")
    with pytest.raises(yf.LabelFormatError, match="split 'test' not found"):
        yf.list_pairs(str(tmp_path), "test")
    os.makedirs(tmp_path / "test" / "images")
    with pytest.raises(yf.LabelFormatError, match="no images"):
        yf.list_pairs(str(tmp_path), "test")
    bad = tmp_path / "data.yaml"
    bad.write_text("names: {0: a, 2: b}\n")
    with pytest.raises(yf.LabelFormatError, match="names"):
        yf.read_data_yaml(str(bad))


def _write_yaml(path, text):
    os.makedirs(os.path.dirname(str(path)), exist_ok=True)
    with open(str(path), "w") as fh:
        fh.write(text)


def _names(pairs, root):
    return [os.path.relpath(p.image_path, root) for p in pairs]


def test_standard_ultralytics_data_yaml_layout(tmp_path):
    root = str(tmp_path / "ds")
    for split, files in (("train", ["t1.jpg"]), ("val", ["v2.png", "v1.jpg"]), ("test", ["x1.jpg"])):
        for f in files:
            _touch(os.path.join(root, "images", split, f))
    # the yaml names the split folders; the extra 'holdout' folder shows the yaml, not the folder name, decides
    _touch(os.path.join(root, "images", "holdout", "h1.jpg"))
    _write_yaml(os.path.join(root, "data.yaml"), "path: .\ntrain: images/train\nval: images/val\n"
                "test: images/holdout\nnames:\n  0: cotton boll\n")
    for split in ("val", "valid"):
        pairs = yf.list_pairs(root, split)
        assert _names(pairs, root) == ["images/val/v1.jpg", "images/val/v2.png"]
        assert pairs[0].label_path == os.path.join(root, "labels", "val", "v1.txt")
    assert _names(yf.list_pairs(root, "test"), root) == ["images/holdout/h1.jpg"]
    assert _names(yf.list_pairs(root, "train"), root) == ["images/train/t1.jpg"]
    assert yf.class_names_for(root, "det") == ("cotton boll",)


def test_data_yaml_split_keys_take_lists_image_list_files_and_single_images(tmp_path):
    root = str(tmp_path / "ds")
    for f in ("a.jpg", "b.jpg", "c.jpg", "d.jpg"):
        _touch(os.path.join(root, "pool", "images", f))      # one flat image folder, COCO style
    _touch(os.path.join(root, "extra", "images", "e.jpg"))
    _write_yaml(os.path.join(root, "lists", "val.txt"),
                "./../pool/images/b.jpg\n\n../pool/images/a.jpg\n" + os.path.join(root, "pool", "images", "c.jpg")
                + "\n../pool/images/a.jpg\n")
    # path: the dataset root below the yaml's folder
    _write_yaml(str(tmp_path / "data.yaml"), "path: ds\ntrain: [pool/images, extra/images]\nval: lists/val.txt\n"
                "test: pool/images/d.jpg\nnames: [cotton boll]\n")
    top = str(tmp_path)
    assert _names(yf.list_pairs(top, "train"), root) == ["extra/images/e.jpg", "pool/images/a.jpg",
                                                         "pool/images/b.jpg", "pool/images/c.jpg",
                                                         "pool/images/d.jpg"]
    val = yf.list_pairs(top, "valid")
    assert _names(val, root) == ["pool/images/a.jpg", "pool/images/b.jpg", "pool/images/c.jpg"]   # a once
    assert val[0].label_path == os.path.join(root, "pool", "labels", "a.txt")
    assert _names(yf.list_pairs(top, "test"), root) == ["pool/images/d.jpg"]
    # written back: the list stays a list
    dy = yf.read_data_yaml(str(tmp_path / "data.yaml"))
    assert dy.train == ("pool/images", "extra/images") and dy.val == "lists/val.txt"
    yf.write_data_yaml(os.path.join(root, "copy.yaml"), dy)
    assert yf.read_data_yaml(os.path.join(root, "copy.yaml")).train == dy.train


def test_data_yaml_falls_back_to_the_split_folders(tmp_path):
    # a Roboflow export's yaml ('../valid/images' from inside the dataset, as Ultralytics reads it)
    root = str(tmp_path)
    _touch(os.path.join(root, "valid", "images", "a.jpg"))
    _write_yaml(os.path.join(root, "data.yaml"), "train: ../train/images\nval: ../valid/images\n"
                "test: ../test/images\nnc: 1\nnames: ['cotton boll']\n")
    pairs = yf.list_pairs(root, "val")
    assert _names(pairs, root) == ["valid/images/a.jpg"]
    assert pairs[0].label_path == os.path.join(root, "valid", "labels", "a.txt")
    # a yaml pointing at a folder that is gone (a moved dataset): the split folders still count
    _touch(os.path.join(root, "images", "test", "b.jpg"))
    _write_yaml(os.path.join(root, "data.yaml"), "path: /nonexistent/dataset\nval: images/val\ntest: images/test\n")
    assert _names(yf.list_pairs(root, "test"), root) == ["images/test/b.jpg"]
    assert _names(yf.list_pairs(root, "valid"), root) == ["valid/images/a.jpg"]


@pytest.mark.parametrize("yaml_text, files, message", [
    ("val: val.txt\n", {"val.txt": "images/a.jpg\nimages/missing.jpg\n"}, "val.txt:2: image 'images/missing.jpg' does not exist"),
    ("val: val.txt\n", {"val.txt": "images/a.jpg\nnotes.md\n"}, "val.txt:2: 'notes.md' is not an image"),
    ("val: [images, gone]\n", {}, "'val' names"),
    ("val: 3\n", {}, "'val' must be a path or a list of paths"),
    ("path: [a]\nval: images\n", {}, "'path' must be a folder path"),
    ("val: images\n", {}, "split 'test' not found"),
    ("val: images\nval: other\n", {}, "key 'val' is given twice, on lines 1 and 2"),
])
def test_data_yaml_errors_name_the_problem(tmp_path, yaml_text, files, message):
    root = str(tmp_path)
    _touch(os.path.join(root, "images", "a.jpg"))
    _write_yaml(os.path.join(root, "data.yaml"), yaml_text)
    for name, text in files.items():
        _write_yaml(os.path.join(root, name), text)
    split = "test" if "test" in message else "val"
    with pytest.raises(yf.LabelFormatError, match=re.escape(message)) as info:
        yf.list_pairs(root, split)
    if split == "test":
        assert "no 'test' entry" in str(info.value)


def test_join_polygons_rasterizes_to_the_union_of_separate_regions():
    rng = np.random.default_rng(3)
    h, w = 60, 80
    # Disjoint blobs (some with holes) traced into polygons by the label tracer.
    mask = np.zeros((h, w), np.uint8)
    for _ in range(6):
        cx, cy, r = rng.integers(8, w - 8), rng.integers(8, h - 8), rng.integers(3, 8)
        cv2.circle(mask, (int(cx), int(cy)), int(r), 1, -1)
    cv2.rectangle(mask, (2, 2), (30, 20), 1, -1)
    cv2.rectangle(mask, (8, 6), (20, 14), 0, -1)          # a hole
    cv2.rectangle(mask, (12, 9), (15, 11), 1, -1)         # an island inside the hole
    from cottonsim_perception.data.generate import mask_to_label_polygons
    polys = mask_to_label_polygons(mask.astype(bool), epsilon_px=0.0)
    assert len(polys) > 2
    separate = np.zeros((h, w), bool)
    for p in polys:
        separate ^= yf.polygon_to_mask(p, h, w)
    joined = yf.join_polygons(polys)
    np.testing.assert_array_equal(yf.polygon_to_mask(joined, h, w), separate)
    np.testing.assert_array_equal(separate, mask.astype(bool))


def test_merge_instances_per_class_gives_one_line_per_class():
    def square(x, y, s):
        return np.array([[x, y], [x + s, y], [x + s, y + s], [x, y + s]], float)
    insts = [yf.LabelInstance(1, yf.polygon_bbox_cxcywh(square(0.1, 0.1, 0.1)), square(0.1, 0.1, 0.1)),
             yf.LabelInstance(0, yf.polygon_bbox_cxcywh(square(0.5, 0.5, 0.1)), square(0.5, 0.5, 0.1)),
             yf.LabelInstance(1, yf.polygon_bbox_cxcywh(square(0.7, 0.2, 0.2)), square(0.7, 0.2, 0.2))]
    merged = yf.merge_instances_per_class(insts)
    assert [m.class_id for m in merged] == [0, 1]
    np.testing.assert_allclose(merged[1].box_cxcywh, [0.5, 0.25, 0.8, 0.3])
    m1 = yf.polygon_to_mask(merged[1].polygon_px(100, 100), 100, 100)
    assert m1.sum() == 10 * 10 + 20 * 20
    with pytest.raises(ValueError, match="polygon 0"):
        yf.join_polygons([np.zeros((2, 2))])


def test_merge_seg_label_files_rewrites_in_place(tmp_path):
    lab = tmp_path / "labels" / "train"
    lab.mkdir(parents=True)
    (lab / "a.txt").write_text("0 0.1 0.1 0.2 0.1 0.2 0.2\n0 0.5 0.5 0.6 0.5 0.6 0.6\n2 0 0 1 0 1 0.05\n")
    (lab / "b.txt").write_text("")
    assert yf.merge_seg_label_files(str(tmp_path)) == (2, 3, 2)
    merged = yf.read_label_file(str(lab / "a.txt"), "seg")
    assert [m.class_id for m in merged] == [0, 2]
    # two triangles of 50 px^2 each in a 100 x 100 image, centres inside counted
    assert yf.polygon_to_mask(merged[0].polygon_px(100, 100), 100, 100).sum() == 2 * yf.polygon_to_mask(
        np.array([[10, 10], [20, 10], [20, 20]], float), 100, 100).sum()
    (lab / "c.txt").write_text("0 0.1 0.1\n")
    with pytest.raises(yf.LabelFormatError, match="c.txt"):
        yf.merge_seg_label_files(str(tmp_path))
    with pytest.raises(yf.LabelFormatError, match="no label files"):
        (tmp_path / "empty" / "images").mkdir(parents=True)
        yf.merge_seg_label_files(str(tmp_path / "empty"))
