"""The segmenter analysis scripts: calibrate_mask_threshold (its scores are evaluate's at each threshold, its
choice is stored) and class_mask_iou."""
import json

import numpy as np

from cottonsim_perception.evaluation.splits import evaluate_split
from cottonsim_perception.inference import Predictor
from cottonsim_perception.nn.models import load_model


def test_scores_are_evaluates_and_the_choice_is_written(tmp_path, perception_script, monkeypatch,
                                                        tiny_seg_weights, self_labelled_seg_data):
    script = perception_script("calibrate_mask_threshold")
    weights, data = tiny_seg_weights, self_labelled_seg_data
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


def test_errors_are_one_line_and_exit_2(tmp_path, perception_script, capsys, tiny_seg_weights,
                                        tiny_det_weights, self_labelled_seg_data):
    script = perception_script("calibrate_mask_threshold")
    seg, det, data = tiny_seg_weights, tiny_det_weights, self_labelled_seg_data
    cases = [(["--weights", seg, "--data", data, "--thresholds", "0.5,1.2"], "--thresholds"),
             (["--weights", seg, "--data", str(tmp_path / "none")], "does not exist"),
             (["--weights", det, "--data", data], "'det' model"),
             (["--weights", seg, "--data", data, "--split", "test"], "split 'test' not found"),
             (["--weights", str(tmp_path / "missing.pt"), "--data", data], "cannot load weights")]
    for argv, message in cases:
        assert script.main(argv) == 2
        assert message in capsys.readouterr().err


def test_class_mask_iou_prints_iou_and_the_pixel_breakdown(perception_script, capsys, tiny_seg_weights,
                                                           tiny_det_weights, self_labelled_seg_data):
    script = perception_script("class_mask_iou")
    for class_id in (0, 1, 2):
        if script.main(["--weights", tiny_seg_weights, "--data", self_labelled_seg_data, "--split", "valid",
                        "--class-id", str(class_id), "--conf", "0.001", "--threads", "1"]) == 0:
            break
    out = capsys.readouterr().out
    assert "mean IoU" in out and "labelled px: missed" in out and "pooled IoU" in out
    assert script.main(["--weights", tiny_det_weights, "--data", self_labelled_seg_data,
                        "--split", "valid"]) == 2
    assert "not a segmenter" in capsys.readouterr().err
