"""scripts/calibrate_mask_threshold: its scores are evaluate's at each threshold, its choice is stored."""
import json
import os

import cv2
import numpy as np
import torch

from cottonsim_perception.data import yolo_format as yf
from cottonsim_perception.evaluate import evaluate_split
from cottonsim_perception.inference import Predictor
from cottonsim_perception.nn.models import ModelConfig, build_model, load_model, save_checkpoint

W, H = 128, 96


def _weights(tmp_path, task):
    torch.manual_seed(0)
    preset = ModelConfig.scene_segmenter if task == "seg" else ModelConfig.boll_detector
    path = str(tmp_path / f"{task}.pt")
    save_checkpoint(path, build_model(preset(width_multiple=0.0625, input_width=W, input_height=H)).eval(),
                    {"epochs": 0})
    return path


def _seg_dataset(root, weights):
    """Two noisy frames labelled with the untrained network's own best mask per class at threshold 0.5
    (its largest outline), so that the scores depend on the mask threshold."""
    rng = np.random.default_rng(3)
    p = Predictor(weights, conf_threshold=0.001, mask_threshold=0.5, threads=1)
    os.makedirs(os.path.join(root, "valid", "images"))
    for i in range(2):
        img = rng.integers(0, 255, (H, W, 3), dtype=np.uint8)
        cv2.imwrite(os.path.join(root, "valid", "images", f"{i}.png"), img[:, :, ::-1])
        det, insts = p.predict(img), []
        for c in range(3):
            of_class = np.flatnonzero(det.classes == c)
            if not len(of_class):
                continue
            mask = det.masks[of_class[np.argmax(det.scores[of_class])]].astype(np.uint8)
            contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
            outline = max(contours, key=cv2.contourArea).reshape(-1, 2).astype(float)
            if len(outline) < 3:
                continue
            poly = outline / [W, H]
            lo, hi = poly.min(0), poly.max(0)
            insts.append(yf.LabelInstance(c, np.r_[(lo + hi) / 2, hi - lo], poly))
        assert insts, "the untrained network gave no mask to label with"
        yf.write_label_file(os.path.join(root, "valid", "labels", f"{i}.txt"), insts, "seg")
    with open(os.path.join(root, "data.yaml"), "w") as fh:
        fh.write("train: valid/images\nval: valid/images\nnames: ['cotton plants', 'ground', 'sky']\n")


def test_scores_are_evaluates_and_the_choice_is_written(tmp_path, perception_script, monkeypatch):
    script = perception_script("calibrate_mask_threshold")
    weights, data = _weights(tmp_path, "seg"), str(tmp_path / "data")
    _seg_dataset(data, weights)
    frames_run = []
    forward = script.Predictor.forward
    monkeypatch.setattr(script.Predictor, "forward", lambda self, rgb: frames_run.append(1) or forward(self, rgb))
    out_json = str(tmp_path / "cal.json")
    thresholds = (0.3, 0.5, 0.7)
    code = script.main(["--weights", weights, "--data", data, "--split", "valid", "--threads", "1",
                        "--thresholds", ",".join(map(str, thresholds)), "--json", out_json, "--write"])
    assert code == 0 and len(frames_run) == 2       # the network ran once per frame, not per threshold
    with open(out_json) as fh:
        report = json.load(fh)
    assert set(report["candidates"]) == {"0.3", "0.5", "0.7"} and report["stored_before"] == 0.5
    assert len({report["candidates"][k]["map50_95"] for k in report["candidates"]}) > 1
    for t in thresholds:       # ... and the scores are still evaluate's
        p = Predictor(weights, conf_threshold=0.001, mask_threshold=t, threads=1)
        res, _, _ = evaluate_split(p, data, "valid", "seg", p.class_names, conf_threshold=0.001)
        row = next(r for r in res["mask"]["rows"] if r["class"] == "all")
        got = report["candidates"][f"{t:g}"]
        assert all(np.isclose(got[k], row[k]) for k in ("p", "r", "map50", "map50_95"))
    assert load_model(weights).inference == {"mask_threshold": report["chosen"]}


def test_errors_are_one_line_and_exit_2(tmp_path, perception_script, capsys):
    script = perception_script("calibrate_mask_threshold")
    seg, det, data = _weights(tmp_path, "seg"), _weights(tmp_path, "det"), str(tmp_path / "data")
    _seg_dataset(data, seg)
    cases = [(["--weights", seg, "--data", data, "--thresholds", "0.5,1.2"], "--thresholds"),
             (["--weights", seg, "--data", str(tmp_path / "none")], "does not exist"),
             (["--weights", det, "--data", data], "'det' model"),
             (["--weights", seg, "--data", data, "--split", "test"], "split 'test' not found"),
             (["--weights", str(tmp_path / "missing.pt"), "--data", data], "cannot load weights")]
    for argv, message in cases:
        assert script.main(argv) == 2
        assert message in capsys.readouterr().err
