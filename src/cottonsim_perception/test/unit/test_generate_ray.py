"""The dataset generator on Ray (a local cluster of 2 CPUs) writes the same files as the worker pool."""
import filecmp
import os

import pytest

from cottonsim_perception.data import generate as g
from cottonsim_world.farm.config import FarmConfig

TINY_FARM = FarmConfig(rows=2, plants_per_row=3, plant_variants=2)


def _config(out_dir, **kw):
    base = dict(out_dir=str(out_dir), images_per_task=4, test_images_per_task=2, seeds=(0, 1),
                test_seeds=(7,), val_fraction=0.5, width=64, height=48, base_farm=TINY_FARM,
                images_per_scene=1, ground_margin_m=3.0)
    base.update(kw)
    return g.DatasetConfig(**base)


def _files(root):
    return sorted(os.path.relpath(os.path.join(d, f), root) for d, _, fs in os.walk(root) for f in fs)


def _assert_same_tree(a, b):
    files = _files(a)
    assert files == _files(b)
    assert any(f.endswith(".jpg") for f in files) and "det/manifest.csv" in files
    _, mismatch, errors = filecmp.cmpfiles(a, b, files, shallow=False)
    assert mismatch == [] and errors == []


def test_plan_ranges_covers_every_scene_once():
    cfg = _config("/nonexistent", images_per_scene=2, images_per_task=6)
    jobs = g.plan_jobs(cfg)
    for size in (1, 2, 5):
        ranges = g.plan_ranges(cfg, jobs, size)
        assert all(1 <= r.scene_hi - r.scene_lo <= size for r in ranges)
        assert sum(r.images(cfg) for r in ranges) == sum(j.total for j in jobs)


@pytest.fixture(scope="module")
def ray_cluster():
    import ray
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_ray_writes_the_pool_files_for_any_range_size(tmp_path, ray_cluster):
    g.generate_dataset(_config(tmp_path / "pool"), progress=False)
    for size in (1, 3):
        out = tmp_path / f"ray{size}"
        summary = g.generate_dataset(_config(out), progress=False,
                                     ray_engine=g.RayEngineConfig(scenes_per_range=size))
        assert summary.images == 2 * (4 + 2)
        _assert_same_tree(str(tmp_path / "pool"), str(out))


@pytest.mark.parametrize("address", ["nohost", "host:0", "host:99999", ":6379", "host:port"])
def test_bad_address_is_refused_with_its_value(address):
    with pytest.raises(ValueError, match="HOST:PORT"):
        g.RayEngineConfig(address=address)


def test_cli_bad_address_exits_2_naming_it(tmp_path, capsys, perception_script):
    rc = perception_script("generate_dataset").main(
        ["--out", str(tmp_path), "--images", "2", "--seeds", "0-1", "--address", "nohost"])
    assert rc == 2
    assert "nohost" in capsys.readouterr().err
