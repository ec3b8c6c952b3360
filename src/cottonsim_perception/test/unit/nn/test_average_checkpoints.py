"""Weight averaging of checkpoints (nn.models.average_checkpoints and scripts/average_weights)."""
import os
import subprocess
import sys

import pytest
import torch

from cottonsim_perception.nn.models import (ModelConfig, average_checkpoints, build_model, load_checkpoint,
                                            load_model, save_checkpoint)

SCRIPT = os.path.join(os.path.dirname(__file__), "..", "..", "..", "scripts", "average_weights")


def _detector(seed):
    torch.manual_seed(seed)
    cfg = ModelConfig.boll_detector(width_multiple=0.0625, input_width=64, input_height=64)
    return build_model(cfg)


def _saved(tmp_path, name, model, meta=None, inference=None):
    path = str(tmp_path / name)
    save_checkpoint(path, model, meta or {"seed": name}, inference=inference)
    return path


def test_the_average_holds_the_mean_of_every_float_tensor(tmp_path):
    a, b, c = (_detector(s) for s in (1, 2, 3))
    # give BatchNorm statistics and counters distinct values, as training would
    for i, m in enumerate((a, b, c)):
        for mod in m.modules():
            if isinstance(mod, torch.nn.BatchNorm2d):
                mod.running_mean.fill_(float(i))
                mod.num_batches_tracked.fill_(10 + i)
    paths = [_saved(tmp_path, f"{n}.pt", m) for n, m in zip("abc", (a, b, c))]
    out = str(tmp_path / "soup.pt")
    meta = average_checkpoints(paths, out)
    soup = load_checkpoint(out)["state_dict"]
    sa, sb, sc = (m.state_dict() for m in (a, b, c))
    for name, t in soup.items():
        if t.is_floating_point():
            assert torch.allclose(t, (sa[name] + sb[name] + sc[name]) / 3, atol=1e-6), name
        else:
            assert torch.equal(t, sa[name]), name       # counters: the first file's
    assert any("running_mean" in k and torch.all(v == 1.0) for k, v in soup.items())
    assert meta["averaged_from"] == [os.path.abspath(p) for p in paths]
    assert [m["seed"] for m in meta["members"]] == ["a.pt", "b.pt", "c.pt"]
    model = load_model(out)                               # a normal, loadable checkpoint
    assert model.config == a.config


def test_averaging_a_checkpoint_with_itself_changes_nothing_and_keeps_inference_settings(tmp_path):
    m = _detector(5).eval()
    path = str(tmp_path / "a.pt")                  # a last.pt: with optimizer state, which the average drops
    save_checkpoint(path, m, {"seed": 5}, optimizer_state={"state": {}}, inference={"mask_threshold": 0.4})
    out = str(tmp_path / "soup.pt")
    average_checkpoints([path, path], out)
    assert load_checkpoint(out)["inference"] == load_checkpoint(path)["inference"]
    assert "optimizer" not in load_checkpoint(out)
    x = torch.rand(1, 3, 64, 64)
    with torch.no_grad():
        assert torch.allclose(load_model(out)(x)[0], m(x)[0], atol=1e-6)


def test_mismatched_or_too_few_checkpoints_are_refused_with_a_message(tmp_path):
    a = _saved(tmp_path, "a.pt", _detector(1))
    with pytest.raises(ValueError, match="at least two"):
        average_checkpoints([a], str(tmp_path / "x.pt"))
    other_size = _saved(tmp_path, "b.pt", _detector(2))
    ck = torch.load(other_size, weights_only=True)
    ck["model_config"]["input_width"] = 96
    torch.save(ck, other_size)
    with pytest.raises(ValueError, match="model_config differs"):
        average_checkpoints([a, other_size], str(tmp_path / "x.pt"))
    broken = _saved(tmp_path, "c.pt", _detector(3))
    ck = torch.load(broken, weights_only=True)
    name = next(k for k, v in ck["state_dict"].items() if v.is_floating_point())
    ck["state_dict"][name][...] = float("nan")
    torch.save(ck, broken)
    with pytest.raises(ValueError, match="non-finite"):
        average_checkpoints([a, broken], str(tmp_path / "x.pt"))
    with pytest.raises(FileNotFoundError):
        average_checkpoints([a, str(tmp_path / "missing.pt")], str(tmp_path / "x.pt"))
    assert not os.path.exists(tmp_path / "x.pt")


def test_script_writes_the_average_and_reports_errors_in_one_line(tmp_path):
    a = _saved(tmp_path, "a.pt", _detector(1))
    b = _saved(tmp_path, "b.pt", _detector(2))
    out = str(tmp_path / "soup.pt")
    ok = subprocess.run([sys.executable, SCRIPT, "--out", out, a, b], capture_output=True, text=True)
    assert ok.returncode == 0 and "average of 2" in ok.stdout and os.path.isfile(out)
    bad = subprocess.run([sys.executable, SCRIPT, "--out", out, a, str(tmp_path / "nope.pt")],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "average_weights: error:" in bad.stderr and "Traceback" not in bad.stderr
