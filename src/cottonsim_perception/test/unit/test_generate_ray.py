"""The dataset generator on Ray (a local cluster of 2 CPUs) writes the same files as the worker pool, and a
range whose worker dies is rendered again."""
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


HERE = os.path.dirname(os.path.abspath(__file__))


@pytest.fixture(scope="module")
def ray_cluster(tmp_path_factory):
    """Ray with 2 CPUs whose workers run generate_fault_injection.install: ranges noted, one doomed on request."""
    import ray

    import generate_fault_injection as fault
    markers = tmp_path_factory.mktemp("range_attempts")
    saved = {k: os.environ.get(k) for k in (fault.MARKERS_ENV, "PYTHONPATH")}
    os.environ[fault.MARKERS_ENV] = str(markers)
    os.environ["PYTHONPATH"] = HERE + os.pathsep + os.environ.get("PYTHONPATH", "")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"worker_process_setup_hook": "generate_fault_injection.install"})
    yield markers
    ray.shutdown()
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


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


def test_a_range_whose_worker_dies_is_rendered_again_and_the_dataset_is_complete(tmp_path, ray_cluster):
    import generate_fault_injection as fault
    markers = str(ray_cluster)
    cfg = _config(tmp_path / "ray")
    ranges = g.plan_ranges(cfg, g.plan_jobs(cfg), 1)
    doomed = ranges[len(ranges) // 2]
    name = fault.range_name(doomed.job, doomed.task, doomed.scene_lo)
    for f in os.listdir(markers):
        os.remove(os.path.join(markers, f))
    with open(os.path.join(markers, fault.DOOMED_FILE), "w") as fh:
        fh.write(name)
    summary = g.generate_dataset(cfg, progress=False, ray_engine=g.RayEngineConfig(scenes_per_range=1, max_retries=1))
    assert fault.attempts(markers, name) == 2                        # lost once, rendered again
    others = [fault.range_name(r.job, r.task, r.scene_lo) for r in ranges if r is not doomed]
    assert [fault.attempts(markers, n) for n in others] == [1] * len(others)
    assert summary.images == 2 * (4 + 2)
    g.generate_dataset(_config(tmp_path / "pool"), progress=False)
    _assert_same_tree(str(tmp_path / "pool"), str(tmp_path / "ray"))   # complete, and the same files

    # without a retry the lost range fails the dataset: the retry above is what completed it
    for f in os.listdir(markers):
        if f != fault.DOOMED_FILE:
            os.remove(os.path.join(markers, f))
    with pytest.raises(Exception, match="(?i)worker|died|crash"):
        g.generate_dataset(_config(tmp_path / "no_retry"), progress=False,
                           ray_engine=g.RayEngineConfig(scenes_per_range=1, max_retries=0))
