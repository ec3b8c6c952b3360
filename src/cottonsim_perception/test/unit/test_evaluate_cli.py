"""The evaluate CLI on a tiny fake dataset with a stub predictor (no network, no weights)."""
import json
import os

import cv2
import numpy as np
import pytest

from cottonsim_perception.evaluation import cli as ev
from cottonsim_perception.data import yolo_format as yf
from cottonsim_perception.types import Detections

W, H = 64, 48
# Each image is filled with a distinct grey level so the stub can recognise it.
# level -> list of (class, polygon in px)
SCENES = {
    "valid": {40: [(0, [[4, 4], [30, 4], [30, 20], [4, 20]]), (1, [[0, 30], [64, 30], [64, 48], [0, 48]])],
              80: [(0, [[10, 10], [20, 10], [20, 30], [10, 30]])]},
    "test": {120: [(1, [[0, 24], [64, 24], [64, 48], [0, 48]])]},
}


def _write_dataset(root, task, layout="split_folders"):
    """SCENES as a YOLO dataset: Roboflow's split folders ({valid,test}/images), or a data.yaml
    naming Ultralytics' folders (images/{val,test}), or image list files over one folder."""
    lists = {}
    for split, scenes in SCENES.items():
        for level, objects in scenes.items():
            name = f"img{level}"
            folder = {"split_folders": os.path.join(split, "images"),
                      "data_yaml": os.path.join("images", "val" if split == "valid" else split),
                      "data_yaml_lists": os.path.join("images", "all")}[layout]
            os.makedirs(os.path.join(root, folder), exist_ok=True)
            image = os.path.join(root, folder, name + ".png")
            cv2.imwrite(image, np.full((H, W, 3), level, np.uint8))
            lists.setdefault(split, []).append(os.path.join(folder, name + ".png"))
            insts = []
            for cls, poly in objects:
                p = np.array(poly, float) / [W, H]
                insts.append(yf.LabelInstance(cls, yf.polygon_bbox_cxcywh(p), p))
            yf.write_label_file(yf.label_path_for(image), insts, task)
    if layout == "data_yaml":
        with open(os.path.join(root, "data.yaml"), "w") as fh:
            fh.write("path: .\ntrain: images/train\nval: images/val\ntest: images/test\nnames: [plant, ground]\n")
    elif layout == "data_yaml_lists":
        for split, files in lists.items():
            with open(os.path.join(root, f"{split}.txt"), "w") as fh:
                fh.write("".join(f"./{f}\n" for f in files))
        with open(os.path.join(root, "data.yaml"), "w") as fh:
            fh.write("val: valid.txt\ntest: test.txt\nnames: {0: plant, 1: ground}\n")


class StubPredictor:
    """Returns the labelled objects of the recognised image; optionally drops one."""

    def __init__(self, task, drop_level=None):
        self.task = task
        self.class_names = ("plant", "ground")
        self.drop_level = drop_level
        self.scenes = {lvl: objs for s in SCENES.values() for lvl, objs in s.items()}

    def predict(self, image_rgb):
        level = int(image_rgb[0, 0, 0])
        objs = [] if level == self.drop_level else self.scenes[level]
        boxes = np.array([yf.polygon_bbox_xyxy(np.array(p, float)) for _, p in objs],
                         np.float32).reshape(-1, 4)
        masks = None
        if self.task == "seg":
            masks = np.stack([yf.polygon_to_mask(np.array(p, float), H, W) for _, p in objs]) \
                if objs else np.zeros((0, H, W), bool)
        return Detections(boxes, np.linspace(0.9, 0.6, len(objs)).astype(np.float32),
                          np.array([c for c, _ in objs], np.int64), masks)


def _run(tmp_path, task, predictor, extra=(), layout="split_folders"):
    data = str(tmp_path / "data")
    _write_dataset(data, task, layout)
    weights = tmp_path / "w.pt"
    weights.write_bytes(b"stub")
    out = str(tmp_path / "out" / "r.json")
    argv = ["--task", task, "--data", data, "--weights", str(weights), "--json", out, *extra]
    code = ev.main(argv, predictor_factory=lambda w, c, i: predictor)
    return code, out


@pytest.mark.parametrize("task, layout", [("seg", "split_folders"), ("det", "split_folders"),
                                          ("det", "data_yaml"), ("seg", "data_yaml_lists")])
def test_perfect_stub_gives_ultralytics_perfect_scores(tmp_path, capsys, task, layout):
    code, out = _run(tmp_path, task, StubPredictor(task), layout=layout)
    assert code == 0
    res = json.load(open(out))
    assert set(res["splits"]) == {"valid", "test", "valid+test"}
    both = res["splits"]["valid+test"]
    assert both["num_images"] == 3
    kinds = ["mask", "box"] if task == "seg" else ["box"]
    for kind in kinds:
        all_row = both[kind]["rows"][0]
        assert all_row["class"] == "all" and all_row["instances"] == 4
        assert all_row["p"] == pytest.approx(1.0) and all_row["r"] == pytest.approx(1.0)
        assert all_row["map50"] == pytest.approx(0.995)
    text = capsys.readouterr().out
    assert "mAP50-95" in text and "plant" in text and "ground" in text


def test_missing_predictions_lower_recall(tmp_path):
    # The stub misses the 'plant' of image 80: in 'valid' one of two plants found
    code, out = _run(tmp_path, "det", StubPredictor("det", drop_level=80), ["--split", "valid"])
    assert code == 0
    rows = {r["class"]: r for r in json.load(open(out))["splits"]["valid"]["box"]["rows"]}
    assert rows["plant"]["instances"] == 2 and rows["plant"]["fn"] == 1
    assert rows["plant"]["r"] == pytest.approx(0.5)
    assert rows["ground"]["r"] == pytest.approx(1.0)
    assert rows["all"]["r"] == pytest.approx(0.75)


def _expect_exit2(capsys, argv, factory=None, fragment=""):
    code = ev.main(argv, predictor_factory=factory or (lambda w, c, i: StubPredictor("det")))
    err = capsys.readouterr().err
    assert code == 2
    assert "Traceback" not in err and fragment in err


def test_error_exits(tmp_path, capsys):
    data = str(tmp_path / "data")
    _write_dataset(data, "det")
    weights = tmp_path / "w.pt"
    weights.write_bytes(b"x")
    out = str(tmp_path / "r.json")
    base = ["--task", "det", "--json", out]
    _expect_exit2(capsys, base + ["--data", str(tmp_path / "nope"), "--weights", str(weights)],
                  fragment="does not exist")
    _expect_exit2(capsys, base + ["--data", data, "--weights", str(tmp_path / "none.pt")],
                  fragment="weights file")
    os.makedirs(os.path.join(data, "train", "images"))
    _expect_exit2(capsys, base + ["--data", data, "--weights", str(weights), "--split", "train"],
                  fragment="no images")
    _expect_exit2(capsys, base + ["--data", data, "--weights", str(weights), "--split", "extra"],
                  fragment="not found")

    def broken(w, c, i):
        raise RuntimeError("bad magic number")
    _expect_exit2(capsys, base + ["--data", data, "--weights", str(weights)], broken,
                  fragment="cannot load weights")
    _expect_exit2(capsys, ["--task", "seg", "--json", out, "--data", data, "--weights", str(weights)],
                  fragment="'det' model")
    # a malformed label is reported with file and line, no traceback
    with open(os.path.join(data, "test", "labels", "img120.txt"), "w") as fh:
        fh.write("0 0.5 0.5 0.2\n")
    _expect_exit2(capsys, base + ["--data", data, "--weights", str(weights)], fragment="img120.txt:1")
    assert not os.path.exists(out)


def test_real_predictor_on_garbage_weights_exits_2(tmp_path, capsys):
    """The default factory (the real Predictor) must turn a bad file into exit 2."""
    data = str(tmp_path / "data")
    _write_dataset(data, "det")
    weights = tmp_path / "garbage.pt"
    weights.write_bytes(b"this is not a checkpoint")
    code = ev.main(["--task", "det", "--data", data, "--weights", str(weights),
                    "--json", str(tmp_path / "r.json")])
    assert code == 2
    assert "cannot load weights" in capsys.readouterr().err


class ExtraBoxStub(StubPredictor):
    """The perfect predictions plus one extra 'plant' box at (40, 2)-(50, 12), scored highest."""

    def predict(self, image_rgb):
        d = super().predict(image_rgb)
        extra = np.array([[40, 2, 50, 12]], np.float32)
        return Detections(np.concatenate([extra, d.boxes_xyxy]), np.concatenate([[0.95], d.scores]).astype(np.float32),
                          np.concatenate([[0], d.classes]).astype(np.int64))


@pytest.mark.parametrize("no_ignore", [False, True])
def test_predictions_on_ignore_boxes_count_nowhere(tmp_path, no_ignore):
    data = str(tmp_path / "data")
    _write_dataset(data, "det")
    # image 40 (valid) gets an ignore box around the extra prediction; image 80 none
    yf.write_label_file(os.path.join(data, "valid", "ignore", "img40.txt"),
                        [yf.LabelInstance(0, np.array([45 / W, 7 / H, 12 / W, 12 / H]))], "det")
    weights = tmp_path / "w.pt"
    weights.write_bytes(b"stub")
    out = str(tmp_path / "r.json")
    argv = ["--task", "det", "--data", data, "--weights", str(weights), "--json", out, "--split", "valid"]
    assert ev.main(argv + (["--no-ignore"] if no_ignore else []),
                   predictor_factory=lambda w, c, i: ExtraBoxStub("det")) == 0
    res = json.load(open(out))["splits"]["valid"]
    plant = {r["class"]: r for r in res["box"]["rows"]}["plant"]
    # the extra box on image 80 (no ignore file) is a false positive either way
    assert plant["tp"] == 2 and plant["fn"] == 0
    assert res["ignored_predictions"] == (0 if no_ignore else 1)
    assert plant["fp"] == (2 if no_ignore else 1)


def test_ignore_regions_rule():
    from cottonsim_perception.evaluation import metrics as M
    preds = np.array([[0, 0, 10, 10], [0, 0, 10, 10], [8, 0, 18, 10], [100, 100, 110, 110]], float)
    matched = np.array([True, False, False, False])
    ignore = np.array([[0, 0, 12, 12]], float)
    # matched predictions stay; the unmatched one inside stays out; 20 % inside and outside stay
    assert M.on_ignore_regions(preds, matched, ignore).tolist() == [False, True, False, False]
    assert M.box_ioa(preds[2:3], ignore)[0, 0] == pytest.approx(0.4)
    assert M.on_ignore_regions(preds, matched, np.zeros((0, 4))).tolist() == [False] * 4
    with pytest.raises(ValueError):
        M.on_ignore_regions(preds, matched[:2], ignore)


def test_mask_threshold_option(tmp_path, capsys):
    import dataclasses

    from cottonsim_perception.nn.postprocess import PostprocessConfig

    class SegStub(StubPredictor):
        post_config = PostprocessConfig(mask_threshold=0.4)          # as if calibrated in the weights

    stub = SegStub("seg")
    code, out = _run(tmp_path, "seg", stub)
    assert code == 0 and json.load(open(out))["mask_threshold"] == 0.4   # the weights' value is recorded
    code, out = _run(tmp_path, "seg", stub, ["--mask-threshold", "0.6"])
    assert code == 0 and json.load(open(out))["mask_threshold"] == 0.6
    assert stub.post_config == dataclasses.replace(PostprocessConfig(mask_threshold=0.4), mask_threshold=0.6)
    capsys.readouterr()
    data, weights = str(tmp_path / "data"), str(tmp_path / "w.pt")
    base = ["--data", data, "--weights", weights, "--json", str(tmp_path / "x.json")]
    _expect_exit2(capsys, ["--task", "seg", *base, "--mask-threshold", "1.0"], lambda w, c, i: SegStub("seg"),
                  "--mask-threshold must be in (0, 1)")
    _expect_exit2(capsys, ["--task", "det", *base, "--mask-threshold", "0.4"], lambda w, c, i: StubPredictor("det"),
                  "segmentation weights only")


def test_flip_tta_option_switches_the_predictor_and_is_recorded(tmp_path, capsys):
    stub = StubPredictor("det")
    code, out = _run(tmp_path, "det", stub)
    assert code == 0 and json.load(open(out))["flip_tta"] is False and not hasattr(stub, "flip_tta")
    code, out = _run(tmp_path, "det", stub, ["--flip-tta"])
    assert code == 0 and json.load(open(out))["flip_tta"] is True and stub.flip_tta is True
    capsys.readouterr()
    base = ["--data", str(tmp_path / "data"), "--weights", str(tmp_path / "w.pt"), "--json", str(tmp_path / "x.json")]
    _expect_exit2(capsys, ["--task", "seg", *base, "--flip-tta"], lambda w, c, i: StubPredictor("seg"),
                  "detection weights only")


def _write_manifest(data, rows):
    with open(os.path.join(data, "manifest.csv"), "w") as fh:
        fh.write("task,split,file,mode\n" + "".join(f"seg,{sp},{f},{m}\n" for sp, f, m in rows))


def test_group_by_a_manifest_column_evaluates_each_value_apart(tmp_path, capsys):
    data = str(tmp_path / "data")
    _write_dataset(data, "seg")
    _write_manifest(data, [("valid", "valid/images/img40.png", "lane"), ("valid", "valid/images/img80.png", "headland"),
                           ("test", "test/images/img120.png", "lane")])
    weights = tmp_path / "w.pt"
    weights.write_bytes(b"stub")
    out = str(tmp_path / "r.json")
    argv = ["--task", "seg", "--data", data, "--weights", str(weights), "--json", out, "--group-by", "mode"]
    assert ev.main(argv, predictor_factory=lambda w, c, i: StubPredictor("seg", drop_level=80)) == 0
    res = json.load(open(out))
    assert res["groups"]["column"] == "mode"
    valid = res["groups"]["splits"]["valid"]
    assert list(valid) == ["headland", "lane"]                     # sorted by value
    assert valid["lane"]["num_images"] == 1 and valid["lane"]["mask"]["rows"][0]["map50"] > 0.99
    assert valid["headland"]["mask"]["rows"][0]["r"] == 0.0          # the stub drops that image's objects
    assert list(res["groups"]["splits"]["test"]) == ["lane"]
    assert "[mode = headland] (1 images)" in capsys.readouterr().out
    # the split's own table is unchanged by grouping
    assert res["splits"]["valid"]["num_images"] == 2


@pytest.mark.parametrize("manifest, message", [
    (None, "no manifest.csv"),
    ([("valid", "valid/images/img40.png", "lane")], "img80.png is not listed"),
])
def test_group_by_errors_name_the_problem(tmp_path, capsys, manifest, message):
    data = str(tmp_path / "data")
    _write_dataset(data, "det")
    if manifest is not None:
        _write_manifest(data, manifest)
    weights = tmp_path / "w.pt"
    weights.write_bytes(b"stub")
    argv = ["--task", "det", "--data", data, "--weights", str(weights), "--json", str(tmp_path / "r.json"),
            "--group-by", "mode"]
    assert ev.main(argv, predictor_factory=lambda w, c, i: StubPredictor("det")) == 2
    assert message in capsys.readouterr().err
    _write_manifest(data, [])
    argv[-1] = "sun"
    assert ev.main(argv, predictor_factory=lambda w, c, i: StubPredictor("det")) == 2
    assert "no column 'sun' to group by; it has task, split, file, mode" in capsys.readouterr().err
