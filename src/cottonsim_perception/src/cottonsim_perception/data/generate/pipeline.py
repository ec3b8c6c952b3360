"""The generation run: which farm renders which images, rendering and labelling them, the worker pool.

``plan_jobs`` splits a ``DatasetConfig`` into one ``FarmJob`` per farm and
split; ``render_farm_job`` renders, labels and writes the images of one job;
``generate_dataset`` runs the jobs (in this process or in spawned worker
processes, one farm at a time each) and writes each task's data.yaml,
manifest.csv and splits.txt. No ROS imports: the CLI is scripts/generate_dataset.
"""
from __future__ import annotations

import csv
import math
import multiprocessing as mp
import os
import sys
import time
from dataclasses import dataclass, field, fields
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import cv2
import numpy as np

from cottonsim_common.validation import require_instance
from cottonsim_perception.data import yolo_format as yf
from cottonsim_world.farm.generator import generate_farm

from .config import SPLITS, DatasetConfig
from .det_labels import boll_boxes, detection_instances
from .poses import camera_transforms, sample_robot_pose
from .randomize import (IMAGE_STREAM, SCENE_STREAM, TASK_CODE, apply_photometric, sample_farm_config,
                        sample_scene_config, seeded_rng)
from .seg_labels import class_ious, segmentation_instances


@dataclass(frozen=True)
class FarmJob:
    """All images of one split that one farm contributes: {task: count}."""

    farm_seed: int
    split: str
    counts: Tuple[Tuple[str, int], ...]

    @property
    def total(self) -> int:
        return sum(n for _, n in self.counts)


def split_seeds(config: DatasetConfig) -> Dict[str, Tuple[int, ...]]:
    """Farm seeds of each split: the last round(val_fraction * S) train seeds are val."""
    seeds = config.seeds
    n_val = 0
    if config.val_fraction > 0.0 and len(seeds) >= 2:
        n_val = min(len(seeds) - 1, max(1, int(round(config.val_fraction * len(seeds)))))
    return {"train": seeds[:len(seeds) - n_val], "val": seeds[len(seeds) - n_val:], "test": config.test_seeds}


def _spread(total: int, buckets: int) -> List[int]:
    """``total`` items over ``buckets`` as evenly as possible (earlier buckets get the extra)."""
    base, extra = divmod(total, buckets)
    return [base + (1 if i < extra else 0) for i in range(buckets)]


def plan_jobs(config: DatasetConfig) -> List[FarmJob]:
    """The per-farm work list. Train/val images are spread evenly over ``seeds``
    (so the val share follows the val farms' share), test images over ``test_seeds``."""
    splits = split_seeds(config)
    pool = splits["train"] + splits["val"]
    per_seed: Dict[Tuple[str, int], Dict[str, int]] = {}
    for task in config.tasks:
        if pool:
            for seed, n in zip(pool, _spread(config.images_per_task, len(pool))):
                split = "train" if seed in splits["train"] else "val"
                per_seed.setdefault((split, seed), {})[task] = n
        if splits["test"]:
            for seed, n in zip(splits["test"], _spread(config.test_images_per_task, len(splits["test"]))):
                per_seed.setdefault(("test", seed), {})[task] = n
    jobs = []
    for (split, seed), counts in per_seed.items():
        job = FarmJob(seed, split, tuple((t, counts.get(t, 0)) for t in config.tasks))
        if job.total > 0:
            jobs.append(job)
    # biggest first: better load balance over the workers
    jobs.sort(key=lambda j: (-j.total, SPLITS.index(j.split), j.farm_seed))
    return jobs


@dataclass
class ImageRecord:
    """One written image (a manifest row)."""

    task: str
    split: str
    file: str
    farm_seed: int
    scene: int
    camera: str
    mode: str
    x_m: float
    y_m: float
    yaw_rad: float
    growth_stage: str
    sun_azimuth_rad: float
    sun_elevation_rad: float
    instances: int
    min_class_iou: float        # seg: the worst per-class polygon round-trip IoU; det: nan
    renderer: str = ""          # the renderer that drew it ('tiny', 'egl', ...)


@dataclass
class DatasetSummary:
    """What ``generate_dataset`` did: counts per task and split, time and speed."""

    counts: Dict[str, Dict[str, int]]
    instances: Dict[str, Dict[str, int]]
    seconds: float
    images: int
    images_per_s: float
    renderer: str
    worst_seg_iou: float
    records: List[ImageRecord] = field(default_factory=list)


def _image_name(farm_seed: int, index: int, ext: str) -> str:
    return f"s{farm_seed:04d}_{index:05d}.{ext}"


@dataclass
class EncodedImage:
    """One rendered image, encoded and labelled, not yet written: what a range task returns."""

    task: str
    name: str                   # file name, e.g. s0003_00012.jpg
    image_bytes: bytes          # the encoded jpg / png file
    label_text: str             # the label file's text
    ignore_text: Optional[str]  # det: the ignore file's text; seg: None
    record: ImageRecord


def _encode_image(rgb: np.ndarray, config: DatasetConfig) -> bytes:
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    params = [cv2.IMWRITE_JPEG_QUALITY, int(config.jpeg_quality)] if config.image_format == "jpg" else []
    ok, buf = cv2.imencode("." + config.image_format, bgr, params)
    if not ok:
        raise OSError(f"could not encode a {config.image_format} image")
    return buf.tobytes()


def _label_text(instances, task: str) -> str:
    lines = [yf.format_label_line(inst, task) for inst in instances]
    return "\n".join(lines) + ("\n" if lines else "")


def scene_count(config: DatasetConfig, images: int) -> int:
    """How many scenes ``images`` images of one task of one farm use."""
    return -(-images // config.images_per_scene)


def render_scene_range(config: DatasetConfig, job: FarmJob, task: str, scene_lo: int, scene_hi: int,
                       on_image: Optional[Callable[[], None]] = None, farm_and_config=None):
    """Yield an ``EncodedImage`` for every image of scenes [scene_lo, scene_hi) of one task of ``job``.

    Every draw depends only on (dataset_seed, farm seed, task, scene / image
    index), so any cut of a job's scenes into ranges gives the same images.
    """
    from cottonsim_world.sensors.camera import CameraModel
    from cottonsim_world.sensors.scene import SensorScene

    count = dict(job.counts)[task]
    cam_cfg = config.camera_config()
    base_T_optical = camera_transforms(config.urdf_path)
    if farm_and_config is None:
        farm_cfg = sample_farm_config(config.base_farm, job.farm_seed, config.variation, config.dataset_seed)
        farm = generate_farm(farm_cfg)
    else:
        farm, farm_cfg = farm_and_config
    renderer = str(cam_cfg.renderer)
    for scene_idx in range(scene_lo, min(scene_hi, scene_count(config, count))):
        s0 = scene_idx * config.images_per_scene
        srng = seeded_rng(config.dataset_seed, SCENE_STREAM, job.farm_seed, TASK_CODE[task], scene_idx)
        scene_cfg = sample_scene_config(srng, config.variation, seed=int(srng.integers(0, 2 ** 31 - 1)),
                                        ground_margin_m=config.ground_margin_m)
        with SensorScene(farm, scene_cfg) as scene:
            camera = CameraModel(scene, cam_cfg)
            renderer = str(getattr(camera, "renderer", cam_cfg.renderer))   # after an EGL fallback
            K = camera.intrinsics().K
            for index in range(s0, min(count, s0 + config.images_per_scene)):
                irng = seeded_rng(config.dataset_seed, IMAGE_STREAM, job.farm_seed, TASK_CODE[task], index)
                shot = sample_robot_pose(farm, task, irng, config.variation, base_T_optical)
                pose = shot.world_T_base @ base_T_optical[shot.camera]
                frame = camera.render(pose)
                ignore_text = None
                if task == "seg":
                    instances = segmentation_instances(frame.semantic, config.labels)
                    ious = class_ious(frame.semantic, instances)
                    finite = [x for x in ious.values() if not math.isnan(x)]
                    worst = min(finite) if finite else float("nan")
                else:
                    bolls = boll_boxes(frame.semantic, frame.depth_m, frame.plant_id, farm, pose, K,
                                       config.labels)
                    instances = detection_instances(bolls, config.width, config.height)
                    ignore_text = _label_text(
                        detection_instances(bolls, config.width, config.height, ignored=True), task)
                    worst = float("nan")
                rgb = apply_photometric(frame.rgb, irng, config.variation)
                name = _image_name(job.farm_seed, index, config.image_format)
                yaw = math.atan2(shot.world_T_base[1, 0], shot.world_T_base[0, 0])
                record = ImageRecord(
                    task, job.split, f"images/{job.split}/{name}", job.farm_seed, scene_idx, shot.camera,
                    shot.mode, float(shot.world_T_base[0, 3]), float(shot.world_T_base[1, 3]), yaw,
                    farm_cfg.growth_stage, scene_cfg.sun_azimuth_rad, scene_cfg.sun_elevation_rad,
                    len(instances), worst, renderer)
                yield EncodedImage(task, name, _encode_image(rgb, config), _label_text(instances, task),
                                   ignore_text, record)
                if on_image is not None:
                    on_image()


def write_encoded_image(config: DatasetConfig, split: str, item: EncodedImage) -> ImageRecord:
    """Write one ``EncodedImage``'s image, label and ignore files under ``out_dir``; returns its record."""
    root = os.path.join(config.out_dir, item.task)
    stem = os.path.splitext(item.name)[0]
    files = [(os.path.join(root, "images", split, item.name), item.image_bytes),
             (os.path.join(root, "labels", split, stem + ".txt"), item.label_text.encode("utf-8"))]
    if item.ignore_text is not None:
        files.append((os.path.join(root, yf.IGNORE_FOLDER, split, stem + ".txt"), item.ignore_text.encode("utf-8")))
    for path, data in files:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "wb") as fh:
            fh.write(data)
    return item.record


def render_farm_job(config: DatasetConfig, job: FarmJob,
                    on_image: Optional[Callable[[], None]] = None) -> List[ImageRecord]:
    """Render, label and write every image of one ``FarmJob``; returns the manifest rows."""
    farm_cfg = sample_farm_config(config.base_farm, job.farm_seed, config.variation, config.dataset_seed)
    farm = generate_farm(farm_cfg)
    records = []
    for task, count in job.counts:
        for item in render_scene_range(config, job, task, 0, scene_count(config, count), on_image,
                                       farm_and_config=(farm, farm_cfg)):
            records.append(write_encoded_image(config, job.split, item))
    return records


# -- worker processes
_COUNTER = None


def _init_worker(counter) -> None:
    global _COUNTER
    _COUNTER = counter
    os.environ.setdefault("OMP_NUM_THREADS", "1")


def _bump() -> None:
    if _COUNTER is not None:
        with _COUNTER.get_lock():
            _COUNTER.value += 1


def _worker(args) -> List[ImageRecord]:
    config, job = args
    return render_farm_job(config, job, _bump)


class _Progress:
    """tqdm when installed, else a progress line printed to stderr now and then."""

    def __init__(self, total: int, enabled: bool) -> None:
        self.total, self.done, self.enabled = total, 0, enabled
        self.t0 = time.monotonic()
        self._last = 0.0
        self._bar = None
        if enabled:
            try:
                from tqdm import tqdm
                self._bar = tqdm(total=total, unit="img", dynamic_ncols=True)
            except ImportError:
                self._bar = None

    def update_to(self, done: int) -> None:
        if not self.enabled or done == self.done:
            return
        if self._bar is not None:
            self._bar.update(done - self.done)
        self.done = done
        if self._bar is None:
            now = time.monotonic()
            if now - self._last >= 2.0 or done == self.total:
                self._last = now
                el = now - self.t0
                rate = done / el if el > 0 else 0.0
                eta = (self.total - done) / rate if rate > 0 else float("nan")
                print(f"\r[{done}/{self.total}] {100.0 * done / max(self.total, 1):5.1f}%  "
                      f"{rate:.2f} img/s  eta {eta:6.0f} s", end="" if done < self.total else "\n",
                      file=sys.stderr, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def _write_manifest(path: str, records: Sequence[ImageRecord]) -> None:
    names = [f.name for f in fields(ImageRecord)]
    with open(path, "w", newline="", encoding="utf-8") as fh:
        wr = csv.writer(fh)
        wr.writerow(names)
        for r in records:
            row = []
            for n in names:
                val = getattr(r, n)
                row.append(f"{val:.4f}" if isinstance(val, float) else val)
            wr.writerow(row)


def generate_dataset(config: DatasetConfig, progress: bool = True, ray_engine=None) -> DatasetSummary:
    """Generate the whole dataset described by ``config`` (see the module docstring).

    ``ray_engine`` (a ``RayEngineConfig``) renders on Ray instead of the worker
    pool (see ``ray_engine.run_on_ray``); the files are the same.

    Existing files with the same names are overwritten; other files in
    ``out_dir`` are left alone. Raises ValueError for an unusable camera
    configuration (e.g. an unknown renderer) before any rendering starts.
    """
    require_instance("config", config, DatasetConfig)
    config.camera_config()                     # fail early on a bad renderer / size
    jobs = plan_jobs(config)
    total = sum(j.total for j in jobs)
    t0 = time.monotonic()
    bar = _Progress(total, progress)
    records: List[ImageRecord] = []
    for job in jobs:
        for task, _ in job.counts:
            for folder in ("images", "labels") + ((yf.IGNORE_FOLDER,) if task == "det" else ()):
                os.makedirs(os.path.join(config.out_dir, task, folder, job.split), exist_ok=True)
    if ray_engine is not None:
        from .ray_engine import run_on_ray
        records = run_on_ray(config, jobs, ray_engine, bar.update_to)
    elif config.workers == 1 or len(jobs) <= 1:
        done = [0]

        def tick() -> None:
            done[0] += 1
            bar.update_to(done[0])

        for job in jobs:
            records.extend(render_farm_job(config, job, tick))
    else:
        # spawn, not fork: a parent that already ran numba's OpenMP kernels cannot fork safely.
        # ProcessPoolExecutor (unlike multiprocessing.Pool) fails instead of hanging when a
        # worker dies, e.g. in a calling script without an ``if __name__ == "__main__"`` guard.
        from concurrent.futures import ProcessPoolExecutor
        from concurrent.futures.process import BrokenProcessPool
        ctx = mp.get_context("spawn")
        counter = ctx.Value("i", 0)
        try:
            with ProcessPoolExecutor(min(config.workers, len(jobs)), mp_context=ctx,
                                     initializer=_init_worker, initargs=(counter,)) as pool:
                pending = [pool.submit(_worker, (config, job)) for job in jobs]
                while not all(p.done() for p in pending):
                    bar.update_to(counter.value)
                    time.sleep(0.5)
                for p in pending:
                    records.extend(p.result())        # re-raises a worker's exception
                bar.update_to(counter.value)
        except BrokenProcessPool as exc:
            raise RuntimeError(
                "a dataset worker process died (out of memory, killed, or the calling script lacks an "
                "'if __name__ == \"__main__\":' guard, which spawned workers need)") from exc
    bar.close()
    seconds = time.monotonic() - t0

    order = {s: i for i, s in enumerate(SPLITS)}
    records.sort(key=lambda r: (r.task, order[r.split], r.file))
    counts: Dict[str, Dict[str, int]] = {}
    inst: Dict[str, Dict[str, int]] = {}
    splits = split_seeds(config)
    for task in config.tasks:
        root = os.path.abspath(os.path.join(config.out_dir, task))
        os.makedirs(root, exist_ok=True)
        names = yf.SEGMENTATION_CLASS_NAMES if task == "seg" else yf.DETECTION_CLASS_NAMES
        have = {s: any(r.task == task and r.split == s for r in records) for s in SPLITS}
        yf.write_data_yaml(os.path.join(root, "data.yaml"), yf.DataYaml(
            path="", train="images/train" if have["train"] else "",
            val="images/val" if have["val"] else "", test="images/test" if have["test"] else "",
            names=tuple(names)))
        task_records = [r for r in records if r.task == task]
        _write_manifest(os.path.join(root, "manifest.csv"), task_records)
        counts[task] = {s: sum(1 for r in task_records if r.split == s) for s in SPLITS}
        inst[task] = {s: sum(r.instances for r in task_records if r.split == s) for s in SPLITS}
        with open(os.path.join(root, "splits.txt"), "w", encoding="utf-8") as fh:
            for s in SPLITS:
                fh.write(f"{s}: farm seeds {list(splits[s])}\n")
    ious = [r.min_class_iou for r in records if r.task == "seg" and not math.isnan(r.min_class_iou)]
    renderer = ",".join(sorted({r.renderer for r in records}))
    return DatasetSummary(counts=counts, instances=inst, seconds=seconds, images=len(records),
                          images_per_s=len(records) / seconds if seconds > 0 else 0.0,
                          renderer=str(renderer), worst_seg_iou=min(ious) if ious else float("nan"),
                          records=records)
