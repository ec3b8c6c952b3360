"""Labelled perception datasets rendered from the simulator (Ultralytics-YOLO layout).

Why: the paper trained its scene segmenter and boll detector on a few dozen
hand-annotated Gazebo screenshots. Our simulator knows the ground truth of
every pixel, so it can render as many exactly labelled images as wanted, from
as many different farms, lights and robot poses as wanted, and keep whole
farms (seeds) apart for an honest test split.

What it writes (``generate_dataset``), per task under ``out_dir/<task>/``::

    data.yaml                      path, train, val, test, nc, names
    images/{train,val,test}/s<farm seed>_<index>.jpg
    labels/{train,val,test}/s<farm seed>_<index>.txt
    ignore/{train,val,test}/s<farm seed>_<index>.txt   (det only: don't-care boll boxes)
    manifest.csv                   one row per image: farm, camera, pose, light, label stats

* task 'seg' (scene segmentation): the primary (front) camera of a robot
  driving through the farm; classes 0 cotton plants (plant and boll pixels),
  1 ground, 2 sky; one polygon per connected region of a class, holes cut in
  with zero-width bridges (see ``mask_to_label_polygons``).
* task 'det' (boll detection): the side cameras (realsense_secondary /
  tertiary) beside a row, or the front camera close to one plant's canopy;
  class 0 cotton boll, one box per *visible* boll within the working range
  (``LabelConfig.max_boll_depth_m``); other visible bolls become ignore boxes
  (see ``boll_boxes``).

How an image is made
--------------------
1. Farm (per farm seed): ``sample_farm_config`` varies plant height and height
   jitter, stem position jitter, missing plants, bolls per plant and growth
   stage (cutout / defoliated) around ``DatasetConfig.base_farm``.
2. Scene (per ``images_per_scene`` images of a farm; building a
   ``SensorScene`` costs seconds): ``sample_scene_config`` varies the sun's
   azimuth and elevation, the light's colour and ambient / diffuse / specular
   strength, the soil colour and texture amplitude and the sky colours.
3. Image: ``sample_robot_pose`` puts the robot in a lane, at a headland
   (turning) or beside / in front of plants; the camera pose is
   ``world_T_base @ base_T_optical`` with base_T_optical from the robot's URDF
   and world_T_base perturbed by a little height, roll and pitch;
   ``apply_photometric`` then changes exposure, contrast, gamma, white
   balance and sensor noise of the rendered RGB. Labels come from the
   rendered ground truth (semantic, depth and plant-id images), never from
   the modified RGB.

Splits: ``DatasetConfig.seeds`` are the train / val farms (a ``val_fraction``
of those *farms* is kept for validation, so val images come from farms the
training never saw); ``test_seeds`` are held-out farms used only for the test
split. All random draws are derived from (dataset_seed, farm seed, task,
image index), so the output does not depend on the number of workers, and
the seg part of ``--task both`` equals ``--task seg``.

Frames: world (z up, ground z = 0) as in ``farm.model``; optical frames as in
``sensors.camera`` (z forward, x right, y down); pixel boxes and polygons in
pixel-edge coordinates (pixel (c, r) covers [c, c+1] x [r, r+1]) as in
``yolo_format``. No ROS imports here: the CLI is scripts/generate_dataset.
"""
from __future__ import annotations

import csv
import math
import multiprocessing as mp
import os
import pathlib
import sys
import time
from dataclasses import dataclass, field, fields, replace
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import cv2
import numpy as np
from scipy.spatial import cKDTree

from cottonsim_perception.data import yolo_format as yf
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.farm.model import Farm, SemanticClass
from cottonsim_world.physics.husky_params import HuskyParams

TASKS = ("seg", "det")
SPLITS = ("train", "val", "test")
IMAGE_FORMATS = ("jpg", "png")

CAMERA_FRONT = "realsense_p"
CAMERA_LEFT = "realsense_secondary"
CAMERA_RIGHT = "realsense_tertiary"
CAMERAS = (CAMERA_FRONT, CAMERA_LEFT, CAMERA_RIGHT)

#: The robot's URDF in this workspace (src/cottonsim_description/urdf/).
DEFAULT_URDF_PATH = str(pathlib.Path(__file__).resolve().parents[4]
                        / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf")

#: Segmentation class ids (the original CottonSim dataset's order).
SEG_PLANT, SEG_GROUND, SEG_SKY = 0, 1, 2


# ============================================================== configuration
def _check_range(name: str, value, lo_bound: float = -math.inf, hi_bound: float = math.inf) -> Tuple[float, float]:
    """Validate a (min, max) pair inside [lo_bound, hi_bound]; returns it as floats."""
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        raise ValueError(f"{name} must be a (min, max) pair, got {value!r}")
    try:
        lo, hi = float(value[0]), float(value[1])
    except (TypeError, ValueError):
        raise ValueError(f"{name} must hold numbers, got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi or lo < lo_bound or hi > hi_bound:
        raise ValueError(f"{name} must satisfy {lo_bound:g} <= min <= max <= {hi_bound:g}, got {value!r}")
    return lo, hi


def _check_number(name: str, value, lo_bound: float = -math.inf, hi_bound: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v < lo_bound or v > hi_bound:
        raise ValueError(f"{name} must be in [{lo_bound:g}, {hi_bound:g}], got {value!r}")
    return v


def _check_int(name: str, value, lo_bound: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo_bound:
        raise ValueError(f"{name} must be an integer >= {lo_bound}, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class LabelConfig:
    """How labels are derived from the rendered ground truth.

    Segmentation
        polygon_epsilon_px: Douglas-Peucker tolerance of the region outlines
            [px]; small enough that the written polygons rasterise back to the
            class masks with IoU >= 0.98.
        min_region_area_px: connected regions whose traced polygon is smaller
            than this [px^2] are not written (a polygon through the outer
            pixels' quarter-pixel insets has about the pixel count minus half
            the perimeter: 2 px^2 drops specks of up to ~4 pixels).
        min_hole_area_px: the same for holes cut into a region [px^2].
        seg_instances: 'class' (default) writes one label line per class
            present, its regions joined by zero-width bridges
            (``yolo_format.merge_instances_per_class``): the paper's label
            style and what the scene segmenter predicts, one mask per class;
            'region' writes one line per connected region (hundreds of
            specks per image, which the mask mAP then counts one by one).
    Boll detection (see ``boll_boxes``)
        boll_extent_factor: a boll's mesh reaches out to about this many boll
            radii (the lumpy locks, up to ~1.45 R); pixels farther from the
            boll centre in 3-D are not that boll's.
        boll_depth_tolerance_m: extra 3-D distance allowed on top of the
            extent [m] (depth quantisation, a boll's fluff).
        min_boll_box_px: bolls whose visible box is narrower or lower than
            this [px] are skipped.
        min_boll_visible_px: fewest visible pixels for a labelled boll.
        min_boll_visible_fraction: fewest visible pixels as a fraction of the
            boll's projected disc (of radius boll radius, inside the image);
            a boll peeking through a leaf with less is not labelled.
        max_boll_depth_m: working range [m]: bolls whose centre lies farther
            than this along the camera's optical axis are not labelled (they
            belong to the rows behind the one the camera faces, out of the
            arm's reach; at 640x480 they are a few pixels wide). Like every
            visible boll that misses the rules above, they are written as
            *ignore* boxes (``ignore/`` beside ``labels/``): evaluation and
            training neither reward nor penalise predictions there.
            ``inf`` labels every depth.
    """

    polygon_epsilon_px: float = 0.3
    min_region_area_px: float = 0.1
    min_hole_area_px: float = 0.1
    seg_instances: str = "class"
    boll_extent_factor: float = 1.5
    boll_depth_tolerance_m: float = 0.03
    min_boll_box_px: float = 4.0
    min_boll_visible_px: int = 8
    min_boll_visible_fraction: float = 0.15
    max_boll_depth_m: float = 1.5

    def __post_init__(self) -> None:
        _check_number("polygon_epsilon_px", self.polygon_epsilon_px, 0.0, 10.0)
        _check_number("min_region_area_px", self.min_region_area_px, 0.0, 1e6)
        _check_number("min_hole_area_px", self.min_hole_area_px, 0.0, 1e6)
        if self.seg_instances not in ("class", "region"):
            raise ValueError(f"LabelConfig.seg_instances must be 'class' or 'region', "
                             f"got {self.seg_instances!r}")
        _check_number("boll_extent_factor", self.boll_extent_factor, 1.0, 5.0)
        _check_number("boll_depth_tolerance_m", self.boll_depth_tolerance_m, 0.0, 1.0)
        _check_number("min_boll_box_px", self.min_boll_box_px, 0.0, 1e4)
        _check_int("min_boll_visible_px", self.min_boll_visible_px, 1)
        _check_number("min_boll_visible_fraction", self.min_boll_visible_fraction, 0.0, 1.0)
        if (isinstance(self.max_boll_depth_m, bool) or not isinstance(self.max_boll_depth_m, (int, float))
                or not self.max_boll_depth_m > 0):     # inf allowed: label every depth
            raise ValueError(f"max_boll_depth_m must be a number > 0 (inf: no limit), "
                             f"got {self.max_boll_depth_m!r}")


@dataclass(frozen=True)
class VariationConfig:
    """What varies between farms, scenes and images, as (min, max) ranges drawn uniformly.

    Per farm (around ``DatasetConfig.base_farm``)
        plant_height_range_m [m]; height_jitter_range (fraction, per plant
        variant); position_jitter_range_m [m]; missing_plant_range
        (fraction); bolls_min_range, bolls_span_range: bolls per plant are
        (lo, lo + span) with lo and span drawn as integers from these;
        defoliated_probability: chance that a farm is 'defoliated'
        instead of 'cutout'.
    Per scene (a group of ``images_per_scene`` images of one farm)
        sun_elevation_range_rad [rad] (azimuth: uniform over the circle);
        light_tint_max: the light's colour is white tinted warm or cool by
        up to this much per channel; ambient_range, diffuse_range,
        specular_range: pybullet light coefficients; soil_brightness_range
        (factor on the default soil colour); soil_tint_max (per channel);
        soil_noise_range: soil texture amplitude; overcast_range: blend of
        the clear sky colours towards grey.
    Per image
        exposure_range (gain), contrast_range (factor about mid-grey),
        gamma_range, white_balance_max (per channel gain +/-),
        noise_std_range (Gaussian sensor noise, 0-255 units);
        camera_height_std_m, camera_pitch_std_rad, camera_roll_std_rad:
        Gaussian perturbations of the robot base (clipped at 2.5 sigma);
        lane_offset_std_m, yaw_std_rad: a driving robot's deviation from
        the lane centre line and heading (clipped at 2.5 sigma);
        headland_probability: seg images taken at a headland (turning at a
        lane end) instead of in a lane; headland_distance_range_m: distance
        beyond the row ends [m]; headland_yaw_max_rad: heading spread at a
        headland around "facing the rows" [rad];
        front_close_probability: det images from the front camera close to
        one plant instead of a side camera; close_distance_range_m:
        horizontal camera-to-stem distance for those [m]; close_yaw_max_rad:
        approach direction spread around perpendicular to the row [rad].
    """

    plant_height_range_m: Tuple[float, float] = (0.85, 1.15)
    height_jitter_range: Tuple[float, float] = (0.0, 0.15)
    position_jitter_range_m: Tuple[float, float] = (0.0, 0.08)
    missing_plant_range: Tuple[float, float] = (0.0, 0.1)
    bolls_min_range: Tuple[int, int] = (4, 12)
    bolls_span_range: Tuple[int, int] = (2, 10)
    defoliated_probability: float = 0.3
    sun_elevation_range_rad: Tuple[float, float] = (0.25, 1.4)
    light_tint_max: float = 0.15
    ambient_range: Tuple[float, float] = (0.4, 0.7)
    diffuse_range: Tuple[float, float] = (0.3, 0.65)
    specular_range: Tuple[float, float] = (0.0, 0.1)
    soil_brightness_range: Tuple[float, float] = (0.7, 1.25)
    soil_tint_max: float = 0.05
    soil_noise_range: Tuple[float, float] = (0.08, 0.35)
    overcast_range: Tuple[float, float] = (0.0, 0.6)
    exposure_range: Tuple[float, float] = (0.75, 1.3)
    contrast_range: Tuple[float, float] = (0.8, 1.2)
    gamma_range: Tuple[float, float] = (0.8, 1.25)
    white_balance_max: float = 0.05
    noise_std_range: Tuple[float, float] = (0.0, 4.0)
    camera_height_std_m: float = 0.01
    camera_pitch_std_rad: float = math.radians(1.5)
    camera_roll_std_rad: float = math.radians(1.0)
    lane_offset_std_m: float = 0.1
    yaw_std_rad: float = math.radians(5.0)
    headland_probability: float = 0.3
    headland_distance_range_m: Tuple[float, float] = (0.8, 5.0)
    headland_yaw_max_rad: float = math.radians(110.0)
    front_close_probability: float = 0.3
    close_distance_range_m: Tuple[float, float] = (0.55, 1.1)
    close_yaw_max_rad: float = math.radians(30.0)

    def __post_init__(self) -> None:
        ranges = {"plant_height_range_m": (0.1, 5.0), "height_jitter_range": (0.0, 0.5),
                  "position_jitter_range_m": (0.0, 1.0), "missing_plant_range": (0.0, 0.95),
                  "bolls_min_range": (0, 60), "bolls_span_range": (0, 60),
                  "sun_elevation_range_rad": (1e-3, math.pi / 2), "ambient_range": (0.0, 2.0),
                  "diffuse_range": (0.0, 2.0), "specular_range": (0.0, 2.0),
                  "soil_brightness_range": (0.0, 3.0), "soil_noise_range": (0.0, 1.0),
                  "overcast_range": (0.0, 1.0), "exposure_range": (0.05, 10.0),
                  "contrast_range": (0.0, 10.0), "gamma_range": (0.05, 10.0),
                  "noise_std_range": (0.0, 100.0), "headland_distance_range_m": (0.0, 50.0),
                  "close_distance_range_m": (0.05, 10.0)}
        for name, (lo, hi) in ranges.items():
            pair = _check_range(name, getattr(self, name), lo, hi)
            if name in ("bolls_min_range", "bolls_span_range"):
                if any(not float(v).is_integer() for v in pair):
                    raise ValueError(f"{name} must hold integers, got {getattr(self, name)!r}")
                pair = (int(pair[0]), int(pair[1]))
            object.__setattr__(self, name, pair)
        if self.bolls_min_range[1] + self.bolls_span_range[1] > 60:
            raise ValueError("bolls_min_range max + bolls_span_range max must be <= 60 bolls per plant")
        for name in ("defoliated_probability", "headland_probability", "front_close_probability"):
            _check_number(name, getattr(self, name), 0.0, 1.0)
        for name in ("light_tint_max", "soil_tint_max", "white_balance_max"):
            _check_number(name, getattr(self, name), 0.0, 0.5)
        for name in ("camera_height_std_m", "camera_pitch_std_rad", "camera_roll_std_rad",
                     "lane_offset_std_m", "yaw_std_rad"):
            _check_number(name, getattr(self, name), 0.0, 1.0)
        _check_number("headland_yaw_max_rad", self.headland_yaw_max_rad, 0.0, math.pi)
        _check_number("close_yaw_max_rad", self.close_yaw_max_rad, 0.0, math.pi / 2)


@dataclass(frozen=True)
class DatasetConfig:
    """One dataset generation run.

    out_dir: output root; each task writes ``out_dir/<task>/``.
    tasks: subset of ('seg', 'det').
    images_per_task: train + val images per task, spread evenly over ``seeds``.
    test_images_per_task: test images per task, spread over ``test_seeds``
        (None: images_per_task // 6 when test seeds are given, else 0).
    seeds: farm seeds for train / val; test_seeds: held-out farm seeds (must
        not overlap ``seeds``).
    val_fraction: fraction of the ``seeds`` farms whose images form the val
        split (rounded, at least one farm when > 0; needs >= 2 seeds).
    width, height: image size [px]; horizontal_fov_rad: None = the camera
        default (the original's plugin, 87 deg).
    renderer: CameraConfig.renderer (None = CameraConfig's default).
    workers: processes, one farm at a time each (1 = in this process).
    image_format: 'jpg' (quality ``jpeg_quality``) or 'png'.
    images_per_scene: images rendered under one sampled light / soil / sky
        before the scene is rebuilt (a rebuild costs seconds).
    dataset_seed: seed of every pose / appearance draw (farm shapes come
        from the farm seeds).
    base_farm: the farm layout varied per farm (its seed is replaced).
    urdf_path: robot URDF giving base_link -> camera optical frames.
    ground_margin_m: textured soil around the farm [m] (SceneConfig.ground_margin_m;
        smaller = faster scene builds, for tests).
    """

    out_dir: str
    tasks: Tuple[str, ...] = TASKS
    images_per_task: int = 1000
    test_images_per_task: Optional[int] = None
    seeds: Tuple[int, ...] = tuple(range(20))
    test_seeds: Tuple[int, ...] = ()
    val_fraction: float = 0.1
    width: int = 640
    height: int = 480
    horizontal_fov_rad: Optional[float] = None
    renderer: Optional[str] = None
    workers: int = 1
    image_format: str = "jpg"
    jpeg_quality: int = 90
    images_per_scene: int = 25
    dataset_seed: int = 0
    base_farm: FarmConfig = field(default_factory=FarmConfig)
    variation: VariationConfig = field(default_factory=VariationConfig)
    labels: LabelConfig = field(default_factory=LabelConfig)
    urdf_path: str = DEFAULT_URDF_PATH
    ground_margin_m: float = 15.0

    def __post_init__(self) -> None:
        if not isinstance(self.out_dir, (str, os.PathLike)) or not str(self.out_dir):
            raise ValueError(f"out_dir must be a non-empty path, got {self.out_dir!r}")
        object.__setattr__(self, "out_dir", str(self.out_dir))
        tasks = (self.tasks,) if isinstance(self.tasks, str) else tuple(self.tasks)
        if not tasks or any(t not in TASKS for t in tasks) or len(set(tasks)) != len(tasks):
            raise ValueError(f"tasks must be a non-empty subset of {TASKS}, got {self.tasks!r}")
        object.__setattr__(self, "tasks", tasks)
        _check_int("images_per_task", self.images_per_task, 0)
        for name in ("seeds", "test_seeds"):
            seq = getattr(self, name)
            if isinstance(seq, (str, bytes)) or not hasattr(seq, "__iter__"):
                raise ValueError(f"{name} must be a sequence of integers, got {seq!r}")
            vals = tuple(_check_int(f"{name} entry", s, 0) for s in seq)
            if len(set(vals)) != len(vals):
                raise ValueError(f"{name} has repeated farm seeds: {vals}")
            object.__setattr__(self, name, vals)
        overlap = sorted(set(self.seeds) & set(self.test_seeds))
        if overlap:
            raise ValueError(f"test_seeds must be held out: seeds {overlap} are also in seeds (train/val)")
        if self.images_per_task > 0 and not self.seeds:
            raise ValueError("seeds must name at least one farm seed when images_per_task > 0")
        if self.test_images_per_task is None:
            default = self.images_per_task // 6 if self.test_seeds else 0
            object.__setattr__(self, "test_images_per_task", default)
        _check_int("test_images_per_task", self.test_images_per_task, 0)
        if self.test_images_per_task > 0 and not self.test_seeds:
            raise ValueError("test_images_per_task > 0 needs test_seeds (held-out farms)")
        _check_number("val_fraction", self.val_fraction, 0.0, 0.9)
        if self.val_fraction > 0.0 and self.images_per_task > 0 and len(self.seeds) < 2:
            raise ValueError("val_fraction > 0 needs at least 2 seeds (val farms are kept apart from "
                             "train farms); give more seeds or set val_fraction to 0")
        for name in ("width", "height"):
            v = _check_int(name, getattr(self, name), 16)
            if v > 4096:
                raise ValueError(f"{name} must be <= 4096 px, got {v}")
        if self.horizontal_fov_rad is not None:
            _check_number("horizontal_fov_rad", self.horizontal_fov_rad, 1e-3, math.pi - 1e-3)
        if self.renderer is not None and not isinstance(self.renderer, str):
            raise ValueError(f"renderer must be a string or None, got {self.renderer!r}")
        _check_int("workers", self.workers, 1)
        if self.image_format not in IMAGE_FORMATS:
            raise ValueError(f"image_format must be one of {IMAGE_FORMATS}, got {self.image_format!r}")
        q = _check_int("jpeg_quality", self.jpeg_quality, 1)
        if q > 100:
            raise ValueError(f"jpeg_quality must be in [1, 100], got {q}")
        _check_int("images_per_scene", self.images_per_scene, 1)
        _check_int("dataset_seed", self.dataset_seed, 0)
        for name, cls in (("base_farm", FarmConfig), ("variation", VariationConfig), ("labels", LabelConfig)):
            if not isinstance(getattr(self, name), cls):
                raise ValueError(f"{name} must be a {cls.__name__}, got {type(getattr(self, name)).__name__}")
        _check_number("ground_margin_m", self.ground_margin_m, 0.0, 1000.0)
        if not os.path.isfile(self.urdf_path):
            raise ValueError(f"urdf_path {self.urdf_path!r} is not a file")

    def camera_config(self):
        """The CameraConfig every image is rendered with (raises ValueError for a bad renderer)."""
        from cottonsim_world.sensors.camera import CameraConfig
        kwargs = dict(width=self.width, height=self.height, plant_id_image=True, rgb_noise_std=0.0)
        if self.horizontal_fov_rad is not None:
            kwargs["horizontal_fov_rad"] = self.horizontal_fov_rad
        if self.renderer is not None:
            kwargs["renderer"] = self.renderer
        return CameraConfig(**kwargs)


# ================================================================ the plan
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


def _rng(*key: int) -> np.random.Generator:
    """A generator from a tuple of non-negative ints (order-sensitive, independent streams)."""
    return np.random.default_rng(np.random.SeedSequence([int(k) for k in key]))


_TASK_CODE = {"seg": 1, "det": 2}
_FARM_STREAM, _SCENE_STREAM, _IMAGE_STREAM = 11, 12, 13


# ============================================================== variation
def sample_farm_config(base: FarmConfig, farm_seed: int, variation: VariationConfig,
                       dataset_seed: int = 0) -> FarmConfig:
    """The FarmConfig of one farm: ``base`` with its seed set to ``farm_seed``
    and the per-farm ranges of ``variation`` drawn from (dataset_seed, farm_seed).

    The position jitter is capped so the lanes keep the robot's clearance.
    """
    rng = _rng(dataset_seed, _FARM_STREAM, farm_seed)
    v = variation
    height = float(rng.uniform(*v.plant_height_range_m))
    # the clearance rule of FarmConfig: free = spacing - width - 2 jitter >= robot + margin
    max_jitter = min(0.25 * base.plant_spacing_m,
                     0.5 * (base.row_spacing_m - base.plant_width_m - base.robot_width_m
                            - base.lane_clearance_margin_m))
    jitter = min(float(rng.uniform(*v.position_jitter_range_m)), max(0.0, max_jitter))
    lo = int(rng.integers(v.bolls_min_range[0], v.bolls_min_range[1] + 1))
    span = int(rng.integers(v.bolls_span_range[0], v.bolls_span_range[1] + 1))
    stage = "defoliated" if rng.random() < v.defoliated_probability else "cutout"
    return replace(base, seed=int(farm_seed), plant_height_m=height,
                   height_jitter_fraction=float(rng.uniform(*v.height_jitter_range)),
                   position_jitter_m=jitter,
                   missing_plant_fraction=float(rng.uniform(*v.missing_plant_range)),
                   bolls_per_plant=(lo, lo + span), growth_stage=stage)


def sample_scene_config(rng: np.random.Generator, variation: VariationConfig, seed: int = 0,
                        ground_margin_m: float = 15.0):
    """A SceneConfig with a random sun, light, soil and sky (see VariationConfig)."""
    from cottonsim_world.sensors.scene import SceneConfig
    v = variation
    d = SceneConfig()
    warmth = rng.uniform(-1.0, 1.0)                        # > 0 warm (evening), < 0 cool (shade)
    t = v.light_tint_max
    light = (1.0 - t * max(0.0, -warmth), 1.0 - 0.3 * t * abs(warmth), 1.0 - t * max(0.0, warmth))
    soil = np.asarray(d.ground_rgb) * rng.uniform(*v.soil_brightness_range)
    soil = soil + rng.uniform(-v.soil_tint_max, v.soil_tint_max, 3)
    overcast = rng.uniform(*v.overcast_range)
    grey = np.array([0.72, 0.74, 0.77])
    zenith = (1 - overcast) * np.asarray(d.sky_zenith_rgb) + overcast * grey + rng.uniform(-0.04, 0.04, 3)
    horizon = (1 - overcast) * np.asarray(d.sky_horizon_rgb) + overcast * (grey + 0.08) + rng.uniform(-0.03, 0.03, 3)

    def rgb(a):
        return tuple(float(x) for x in np.clip(a, 0.0, 1.0))

    return SceneConfig(
        ground_rgb=rgb(soil), soil_noise_amplitude=float(rng.uniform(*v.soil_noise_range)),
        sky_zenith_rgb=rgb(zenith), sky_horizon_rgb=rgb(horizon),
        sun_azimuth_rad=float(rng.uniform(-math.pi, math.pi)),
        sun_elevation_rad=float(rng.uniform(*v.sun_elevation_range_rad)),
        light_rgb=rgb(light), ambient_coeff=float(rng.uniform(*v.ambient_range)),
        diffuse_coeff=float(rng.uniform(*v.diffuse_range)), specular_coeff=float(rng.uniform(*v.specular_range)),
        collision_source="primitives",       # the ray-cast world is not used here: build the cheap one
        ground_margin_m=float(ground_margin_m), seed=int(seed))


def apply_photometric(rgb: np.ndarray, rng: np.random.Generator, variation: VariationConfig) -> np.ndarray:
    """Exposure, contrast, gamma, white balance and sensor noise on a uint8 RGB image.

    out = clip(255 * ((contrast * (wb * exposure * x - 0.5) + 0.5) ** gamma) + noise),
    x = rgb / 255. Returns a new uint8 array of the same shape.
    """
    img = np.asarray(rgb)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise ValueError(f"apply_photometric: expected an (H, W, 3) uint8 image, got {img.shape} {img.dtype}")
    v = variation
    exposure = rng.uniform(*v.exposure_range)
    contrast = rng.uniform(*v.contrast_range)
    gamma = rng.uniform(*v.gamma_range)
    wb = 1.0 + rng.uniform(-v.white_balance_max, v.white_balance_max, 3)
    noise = rng.uniform(*v.noise_std_range)
    x = img.astype(np.float32) * np.float32(1.0 / 255.0)
    x *= (exposure * wb).astype(np.float32)
    x = (x - 0.5) * np.float32(contrast) + 0.5
    np.clip(x, 0.0, 1.0, out=x)
    x **= np.float32(gamma)
    x *= 255.0
    if noise > 0.0:
        x += rng.standard_normal(x.shape, dtype=np.float32) * np.float32(noise)
    return np.clip(x + 0.5, 0, 255).astype(np.uint8)


# ================================================================== poses
def _clipped_normal(rng: np.random.Generator, std: float) -> float:
    return float(np.clip(rng.normal(0.0, std), -2.5 * std, 2.5 * std)) if std > 0 else 0.0


def base_pose_matrix(x_m: float, y_m: float, yaw_rad: float, z_m: float,
                     roll_rad: float = 0.0, pitch_rad: float = 0.0) -> np.ndarray:
    """world_T_base: translation (x, y, z) and rotation Rz(yaw) Ry(pitch) Rx(roll)."""
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    out = np.eye(4)
    out[:3, :3] = rz @ ry @ rx
    out[:3, 3] = (x_m, y_m, z_m)
    return out


@dataclass(frozen=True)
class RobotShot:
    """Where one image is taken from: the camera and the robot's base pose."""

    camera: str
    mode: str                   # 'lane', 'headland', 'side', 'close'
    world_T_base: np.ndarray    # 4x4


def _clear_of_plants(farm: Farm, points_xy: np.ndarray, margin_m: float) -> bool:
    """True when every point is farther than half a plant width + margin from every stem."""
    stems = farm.plant_positions()
    if len(stems) == 0:
        return True
    width = max((p.model.width_m for p in farm.plants), default=0.7)
    d = np.linalg.norm(points_xy[:, None, :] - stems[None, :, :], axis=2)
    return bool(np.all(d > 0.5 * width + margin_m))


def sample_robot_pose(farm: Farm, task: str, rng: np.random.Generator, variation: VariationConfig,
                      base_T_optical: Dict[str, np.ndarray], base_height_m: float = HuskyParams().base_link_height_m,
                      max_tries: int = 30) -> RobotShot:
    """A random robot pose for one image of ``task`` (see the module docstring).

    seg: 'lane' (in a lane, heading along it, offset and yaw noise) or
    'headland' (beyond a row end, turning); camera realsense_p.
    det: 'side' (in a lane next to a row, the secondary or tertiary camera
    facing the row) or 'close' (the front camera 0.55-1.1 m from one plant,
    looking at it roughly across the row).
    Poses whose camera or base centre would be inside a plant's canopy are
    redrawn (up to ``max_tries``; then the last draw is used).
    """
    if task not in TASKS:
        raise ValueError(f"task must be one of {TASKS}, got {task!r}")
    cfg = farm.config if isinstance(farm.config, FarmConfig) else FarmConfig()
    v = variation
    lanes = farm.lanes
    if not lanes:
        raise ValueError("farm has no lanes: cannot place the robot")
    y_lo = min(l.y_start_m for l in lanes)
    y_hi = max(l.y_end_m for l in lanes)
    x_lanes = np.array([l.x_m for l in lanes])
    shot = None
    for _ in range(max_tries):
        roll = _clipped_normal(rng, v.camera_roll_std_rad)
        pitch = _clipped_normal(rng, v.camera_pitch_std_rad)
        z = base_height_m + _clipped_normal(rng, v.camera_height_std_m)
        if task == "seg":
            camera = CAMERA_FRONT
            if rng.random() < v.headland_probability:
                mode = "headland"
                south = rng.random() < 0.5
                dist = rng.uniform(*v.headland_distance_range_m)
                y = y_lo - dist if south else y_hi + dist
                x = rng.uniform(x_lanes.min() - 1.0, x_lanes.max() + 1.0)
                into_rows = math.pi / 2 if south else -math.pi / 2
                yaw = into_rows + rng.uniform(-v.headland_yaw_max_rad, v.headland_yaw_max_rad)
            else:
                mode = "lane"
                lane = lanes[int(rng.integers(len(lanes)))]
                x = lane.x_m + _clipped_normal(rng, v.lane_offset_std_m)
                y = rng.uniform(y_lo - 2.5, y_hi + 1.0)
                north = rng.random() < 0.5
                if not north:
                    y = y_lo + y_hi - y          # mirror: heading south starts at the north end
                yaw = (math.pi / 2 if north else -math.pi / 2) + _clipped_normal(rng, v.yaw_std_rad)
        else:
            plants = farm.plants
            if not plants:
                raise ValueError("farm has no plants: cannot take boll detection images")
            if rng.random() < v.front_close_probability:
                mode, camera = "close", CAMERA_FRONT
                target = plants[int(rng.integers(len(plants)))]
                across = 0.0 if rng.random() < 0.5 else math.pi        # look towards +x or -x
                view = across + rng.uniform(-v.close_yaw_max_rad, v.close_yaw_max_rad)
                d = rng.uniform(*v.close_distance_range_m)
                cam_xy = np.array([target.x_m, target.y_m]) - d * np.array([math.cos(view), math.sin(view)])
                yaw = view + _clipped_normal(rng, v.yaw_std_rad)
                offset = base_T_optical[camera][:2, 3]
                c, s = math.cos(yaw), math.sin(yaw)
                x = cam_xy[0] - (c * offset[0] - s * offset[1])
                y = cam_xy[1] - (s * offset[0] + c * offset[1])
            else:
                mode = "side"
                camera = CAMERA_LEFT if rng.random() < 0.5 else CAMERA_RIGHT
                row = int(rng.integers(cfg.rows))
                row_x = cfg.row_x_m(row)
                east = rng.random() < 0.5                   # the lane east (+x) or west of the row
                x = row_x + (0.5 if east else -0.5) * cfg.row_spacing_m + _clipped_normal(rng, v.lane_offset_std_m)
                y = rng.uniform(cfg.first_plant_y_m - 0.3, cfg.last_plant_y_m + 0.3)
                towards = math.pi if east else 0.0           # direction from the camera to the row
                # the camera's horizontal viewing direction in base_link
                axis = base_T_optical[camera][:3, 2]
                cam_dir = math.atan2(axis[1], axis[0])
                yaw = towards - cam_dir + _clipped_normal(rng, v.yaw_std_rad)
        base = base_pose_matrix(x, y, yaw, z, roll, pitch)
        cam = base @ base_T_optical[camera]
        shot = RobotShot(camera, mode, base)
        if _clear_of_plants(farm, np.array([cam[:2, 3], base[:2, 3]]), 0.05):
            break
    return shot


# ================================================================= labels
def _bridge_holes(outer: np.ndarray, holes: Sequence[np.ndarray]) -> np.ndarray:
    """One polygon = ``outer`` with each hole joined in by a zero-width bridge.

    Each hole is cut open at its vertex nearest to the outline and spliced in
    after that outline vertex (outline ... o_i, h_j, h_j+1, ..., h_j, o_i ...).
    Even-odd filling of the result is the outer region minus the holes: a
    bridge's two coincident edges toggle the fill twice, i.e. not at all,
    also where a bridge passes over another hole.
    """
    poly = np.asarray(outer, dtype=np.float64)
    if not holes:
        return poly
    hs = [np.asarray(hole, dtype=np.float64) for hole in holes]
    dist, idx = cKDTree(poly).query(np.concatenate(hs))      # one query for all hole vertices
    splice: Dict[int, List[np.ndarray]] = {}
    start = 0
    for h in hs:
        seg = slice(start, start + len(h))
        start += len(h)
        j = int(np.argmin(dist[seg]))
        ring = np.concatenate([h[j:], h[:j + 1]])     # starts and ends at the bridge vertex h[j]
        splice.setdefault(int(idx[seg][j]), []).append(ring)
    parts, start = [], 0
    for i in sorted(splice):
        parts.append(poly[start:i + 1])
        for ring in splice[i]:
            parts.append(ring)
            parts.append(poly[i:i + 1])               # back on the outline after each hole
        start = i + 1
    parts.append(poly[start:])
    return np.concatenate(parts)


def _holes(mask: np.ndarray) -> np.ndarray:
    """Background pixels not 4-connected to the image border (pockets enclosed by the mask)."""
    h, w = mask.shape
    bg = np.zeros((h + 2, w + 2), dtype=np.uint8)
    bg[1:-1, 1:-1] = ~mask
    bg[0, :] = bg[-1, :] = 1
    bg[:, 0] = bg[:, -1] = 1
    # flood the background from the frame; what stays 1 is enclosed
    cv2.floodFill(bg, None, (0, 0), 0, flags=4)
    return bg[1:-1, 1:-1].astype(bool)


def mask_to_label_polygons(mask: np.ndarray, epsilon_px: float = 0.3, min_area_px: float = 0.1,
                           min_hole_area_px: Optional[float] = None) -> List[np.ndarray]:
    """YOLO polygons [px, pixel edges] of a class mask: one per connected region, holes cut in.

    The 8-connected regions are traced with ``yolo_format.mask_to_polygons``
    (Douglas-Peucker ``epsilon_px``; regions whose polygon area is below
    ``min_area_px`` [px^2] are skipped). The holes (background pockets
    enclosed by a region) are traced the same way (skipped below
    ``min_hole_area_px``, default ``min_area_px``) and joined to the outline
    of the region around them by zero-width bridges (``_bridge_holes``),
    because a YOLO label line cannot hold a hole. An island inside a hole is
    a region (and polygon) of its own. ``yolo_format.polygon_to_mask`` of the
    polygons then reproduces the mask up to the tolerance and the skipped specks.
    """
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask_to_label_polygons: expected an (H, W) mask, got shape {m.shape}")
    m = m.astype(bool)
    if not m.any():
        return []
    hole_area = min_area_px if min_hole_area_px is None else min_hole_area_px
    holes_mask = _holes(m)
    # regions inside a hole (islands) are not outer contours of ``m``: trace them recursively
    islands = m & _holes(holes_mask) if holes_mask.any() else None
    inner = (mask_to_label_polygons(islands, epsilon_px, min_area_px, min_hole_area_px)
             if islands is not None and islands.any() else [])
    outers = yf.mask_to_polygons(m, epsilon_px, min_area_px)
    if not holes_mask.any():
        return outers
    h, w = m.shape
    _, lab = cv2.connectedComponents(m.astype(np.uint8), connectivity=8)

    def region_at(px: float, py: float) -> int:
        return int(lab[min(max(int(py), 0), h - 1), min(max(int(px), 0), w - 1)])

    # outline vertices lie a quarter pixel inside their region's boundary pixels
    by_region = {region_at(*p[0]): k for k, p in enumerate(outers)}
    hole_lists: Dict[int, List[np.ndarray]] = {}
    for hole in yf.mask_to_polygons(holes_mask, epsilon_px, hole_area):
        # the pixel above the hole's top-most vertex belongs to the region around it
        top = hole[int(np.argmin(hole[:, 1]))]
        col = min(max(int(top[0]), 0), w - 1)
        row = int(top[1])
        while row >= 0 and not m[row, col]:
            row -= 1
        if row < 0:
            continue                                  # cannot happen for a true hole
        k = by_region.get(int(lab[row, col]))
        if k is not None:
            hole_lists.setdefault(k, []).append(hole)
    return [_bridge_holes(p, hole_lists[k]) if k in hole_lists else p for k, p in enumerate(outers)] + inner


def segmentation_masks(semantic: np.ndarray) -> Dict[int, np.ndarray]:
    """Per segmentation class id, its (H, W) bool mask (plant includes boll pixels)."""
    sem = np.asarray(semantic)
    return {SEG_PLANT: (sem == SemanticClass.PLANT) | (sem == SemanticClass.BOLL),
            SEG_GROUND: sem == SemanticClass.GROUND,
            SEG_SKY: sem == SemanticClass.SKY}


def segmentation_instances(semantic: np.ndarray, config: LabelConfig = LabelConfig()) -> List[yf.LabelInstance]:
    """Scene-segmentation labels of one semantic image, normalised to [0, 1]."""
    sem = np.asarray(semantic)
    if sem.ndim != 2:
        raise ValueError(f"semantic must be an (H, W) image, got shape {sem.shape}")
    h, w = sem.shape
    scale = np.array([w, h], dtype=np.float64)
    out = []
    for cls, mask in segmentation_masks(sem).items():
        for poly in mask_to_label_polygons(mask, config.polygon_epsilon_px, config.min_region_area_px,
                                           config.min_hole_area_px):
            norm = np.clip(poly / scale, 0.0, 1.0)
            out.append(yf.LabelInstance(cls, yf.polygon_bbox_cxcywh(norm), norm))
    if config.seg_instances == "class":
        out = yf.merge_instances_per_class(out)
    return out


def rasterise_instances(instances: Sequence[yf.LabelInstance], height: int, width: int,
                        num_classes: int = 3) -> np.ndarray:
    """(num_classes, H, W) bool: per class, the union of its polygons (boxes for box labels).

    Same pixel rule as ``yolo_format.polygon_to_mask`` (pixel centre inside,
    even-odd), evaluated in each polygon's bounding box for speed.
    """
    out = np.zeros((num_classes, height, width), dtype=bool)
    for inst in instances:
        if not 0 <= inst.class_id < num_classes:
            raise ValueError(f"class id {inst.class_id} outside [0, {num_classes})")
        poly = inst.polygon_px(width, height)
        if poly is None:
            x1, y1, x2, y2 = inst.box_xyxy_px(width, height)
            poly = np.array([[x1, y1], [x2, y1], [x2, y2], [x1, y2]])
        c0 = max(0, int(math.floor(poly[:, 0].min())) - 1)
        r0 = max(0, int(math.floor(poly[:, 1].min())) - 1)
        c1 = min(width, int(math.ceil(poly[:, 0].max())) + 1)
        r1 = min(height, int(math.ceil(poly[:, 1].max())) + 1)
        if c1 <= c0 or r1 <= r0:
            continue
        out[inst.class_id, r0:r1, c0:c1] |= yf.polygon_to_mask(poly - [c0, r0], r1 - r0, c1 - c0)
    return out


def class_ious(semantic: np.ndarray, instances: Sequence[yf.LabelInstance]) -> Dict[int, float]:
    """Per segmentation class: IoU of the rasterised labels with the ground-truth mask
    (nan for a class absent from both)."""
    sem = np.asarray(semantic)
    h, w = sem.shape
    drawn = rasterise_instances(instances, h, w, 3)
    out = {}
    for cls, mask in segmentation_masks(sem).items():
        union = np.count_nonzero(mask | drawn[cls])
        out[cls] = float(np.count_nonzero(mask & drawn[cls]) / union) if union else float("nan")
    return out


@dataclass(frozen=True)
class BollLabel:
    """One visible boll in an image.

    box_xyxy_px: (x1, y1, x2, y2) in pixel-edge coordinates (tight around
    the visible pixels); plant_id / boll_index: which boll of the farm;
    depth_m: the boll centre's depth along the optical axis; visible_px:
    its visible pixel count; visible_fraction: of its projected disc;
    ignore: True for a visible boll that is not labelled (outside the
    working range or below the visibility rules of ``LabelConfig``).
    """

    box_xyxy_px: Tuple[float, float, float, float]
    plant_id: int
    boll_index: int
    depth_m: float
    visible_px: int
    visible_fraction: float
    ignore: bool = False


def boll_boxes(semantic: np.ndarray, depth_m: np.ndarray, plant_id: Optional[np.ndarray], farm: Farm,
               world_T_optical: np.ndarray, K: np.ndarray,
               config: LabelConfig = LabelConfig()) -> List[BollLabel]:
    """Boxes of the bolls of ``farm`` that are visible in one rendered frame.

    Rule: every boll centre c (radius R) in front of the camera is projected
    with K. A pixel belongs to the boll when it is a BOLL pixel of the
    semantic image, of the boll's own plant (when a plant-id image is
    given), and its back-projected 3-D point (from the depth image) lies
    within ``boll_extent_factor * R + boll_depth_tolerance_m`` of c; a pixel
    claimed by two bolls goes to the nearer centre. So a boll hidden behind
    a leaf has no pixels (the leaf's pixels are PLANT, and a boll seen
    through a gap that is farther away is too far from c). The boll is
    labelled when its centre depth is <= ``max_boll_depth_m``, it has >=
    ``min_boll_visible_px`` pixels, they cover >= ``min_boll_visible_fraction``
    of its projected disc (radius f R / z, clipped to the image) and their box
    is >= ``min_boll_box_px`` wide and high. The box is the visible pixels'
    extent (x2 = last column + 1). Every other boll with a visible pixel is
    returned with ``ignore=True`` (a don't-care region for evaluation and
    training).
    """
    sem = np.asarray(semantic)
    depth = np.asarray(depth_m, dtype=np.float64)
    if sem.ndim != 2 or depth.shape != sem.shape:
        raise ValueError(f"semantic {sem.shape} and depth {depth.shape} must be (H, W) images of one size")
    if plant_id is not None and np.asarray(plant_id).shape != sem.shape:
        raise ValueError(f"plant_id image {np.asarray(plant_id).shape} must match semantic {sem.shape}")
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)):
        raise ValueError("K must be a finite 3x3 intrinsics matrix")
    pose = np.asarray(world_T_optical, dtype=np.float64)
    if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
        raise ValueError("world_T_optical must be a finite 4x4 transform")
    h, w = sem.shape
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    is_boll = sem == SemanticClass.BOLL
    if not is_boll.any():
        return []
    pids = np.asarray(plant_id) if plant_id is not None else None
    visible_plants = set(np.unique(pids[is_boll]).tolist()) if pids is not None else None

    centres, radii, owners, indices = [], [], [], []
    for plant in farm.plants:
        if visible_plants is not None and plant.plant_id not in visible_plants:
            continue
        if len(plant.model.boll_radii) == 0:
            continue
        centres.append(plant.boll_centres_world())
        radii.append(np.asarray(plant.model.boll_radii, dtype=np.float64))
        owners.append(np.full(len(radii[-1]), plant.plant_id))
        indices.append(np.arange(len(radii[-1])))
    if not centres:
        return []
    cw = np.concatenate(centres)
    radius = np.concatenate(radii)
    owner = np.concatenate(owners)
    index = np.concatenate(indices)
    r_wo, t_wo = pose[:3, :3], pose[:3, 3]
    c_opt = (cw - t_wo) @ r_wo                        # centres in the optical frame
    extent = config.boll_extent_factor * radius + config.boll_depth_tolerance_m
    z = c_opt[:, 2]
    front = z - extent > 1e-3
    u = fx * c_opt[:, 0] / np.where(front, z, 1.0) + cx
    v = fy * c_opt[:, 1] / np.where(front, z, 1.0) + cy
    r_px = fx * extent / np.maximum(z - extent, 1e-3)

    best = np.full((h, w), np.inf)
    claim = np.full((h, w), -1, dtype=np.int64)
    windows = {}
    for k in np.nonzero(front)[0]:
        c0 = max(0, int(math.floor(u[k] - r_px[k])))
        c1 = min(w, int(math.ceil(u[k] + r_px[k])) + 1)
        r0 = max(0, int(math.floor(v[k] - r_px[k])))
        r1 = min(h, int(math.ceil(v[k] + r_px[k])) + 1)
        if c0 >= c1 or r0 >= r1:
            continue
        cand = is_boll[r0:r1, c0:c1]
        if pids is not None:
            cand = cand & (pids[r0:r1, c0:c1] == owner[k])
        if not cand.any():
            continue
        zz = depth[r0:r1, c0:c1]
        xs = (np.arange(c0, c1) - cx) / fx
        ys = (np.arange(r0, r1) - cy) / fy
        with np.errstate(invalid="ignore"):
            d2 = ((xs[None, :] * zz - c_opt[k, 0]) ** 2 + (ys[:, None] * zz - c_opt[k, 1]) ** 2
                  + (zz - c_opt[k, 2]) ** 2)
            take = cand & (d2 <= extent[k] ** 2) & (d2 < best[r0:r1, c0:c1])
        if not take.any():
            continue
        best[r0:r1, c0:c1][take] = d2[take]
        claim[r0:r1, c0:c1][take] = k
        windows[k] = (r0, r1, c0, c1)

    out = []
    for k, (r0, r1, c0, c1) in windows.items():
        mine = claim[r0:r1, c0:c1] == k
        n_px = int(np.count_nonzero(mine))
        if n_px == 0:       # every pixel went to a nearer boll
            continue
        rows = np.nonzero(mine.any(axis=1))[0]
        cols = np.nonzero(mine.any(axis=0))[0]
        x1, x2 = c0 + cols[0], c0 + cols[-1] + 1
        y1, y2 = r0 + rows[0], r0 + rows[-1] + 1
        # the boll's projected disc (radius f R / z) inside the image
        rd = fx * radius[k] / z[k]
        d0, d1 = max(0, int(math.floor(u[k] - rd))), min(w, int(math.ceil(u[k] + rd)) + 1)
        e0, e1 = max(0, int(math.floor(v[k] - rd))), min(h, int(math.ceil(v[k] + rd)) + 1)
        if d0 < d1 and e0 < e1:
            gu = np.arange(d0, d1)[None, :] - u[k]
            gv = np.arange(e0, e1)[:, None] - v[k]
            disc = int(np.count_nonzero(gu ** 2 + gv ** 2 <= rd ** 2))
        else:
            disc = 0
        frac = n_px / max(disc, 1)
        labelled = (z[k] <= config.max_boll_depth_m
                    and n_px >= config.min_boll_visible_px
                    and x2 - x1 >= config.min_boll_box_px and y2 - y1 >= config.min_boll_box_px
                    and frac >= config.min_boll_visible_fraction)
        out.append(BollLabel((float(x1), float(y1), float(x2), float(y2)), int(owner[k]), int(index[k]),
                             float(z[k]), n_px, float(min(frac, 9.99)), ignore=not labelled))
    out.sort(key=lambda b: (b.box_xyxy_px[1], b.box_xyxy_px[0]))
    return out


def detection_instances(bolls: Sequence[BollLabel], width: int, height: int,
                        ignored: bool = False) -> List[yf.LabelInstance]:
    """YOLO box lines (class 0 cotton boll, normalised) of ``boll_boxes``' output:
    the labelled bolls, or with ``ignored`` the ignore boxes."""
    out = []
    for b in bolls:
        if b.ignore != ignored:
            continue
        x1, y1, x2, y2 = b.box_xyxy_px
        out.append(yf.LabelInstance(0, np.array([(x1 + x2) / 2 / width, (y1 + y2) / 2 / height,
                                                 (x2 - x1) / width, (y2 - y1) / height])))
    return out


# ============================================================== generation
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


def _write_image(path: str, rgb: np.ndarray, config: DatasetConfig) -> None:
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    params = [cv2.IMWRITE_JPEG_QUALITY, int(config.jpeg_quality)] if config.image_format == "jpg" else []
    if not cv2.imwrite(path, bgr, params):
        raise OSError(f"could not write image {path!r}")


def _camera_transforms(urdf_path: str) -> Dict[str, np.ndarray]:
    from cottonsim_world.robot.urdf_model import UrdfModel
    urdf = UrdfModel.from_file(urdf_path)
    return {cam: urdf.fixed_transform("base_link", f"{cam}_color_optical_frame") for cam in CAMERAS}


def render_farm_job(config: DatasetConfig, job: FarmJob,
                    on_image: Optional[Callable[[], None]] = None) -> List[ImageRecord]:
    """Render, label and write every image of one ``FarmJob``; returns the manifest rows."""
    from cottonsim_world.sensors.camera import CameraModel
    from cottonsim_world.sensors.scene import SensorScene

    cam_cfg = config.camera_config()
    base_T_optical = _camera_transforms(config.urdf_path)
    farm_cfg = sample_farm_config(config.base_farm, job.farm_seed, config.variation, config.dataset_seed)
    farm = generate_farm(farm_cfg)
    ext = config.image_format
    records = []
    renderer = str(cam_cfg.renderer)
    for task, count in job.counts:
        root = os.path.join(config.out_dir, task)
        img_dir = os.path.join(root, "images", job.split)
        lbl_dir = os.path.join(root, "labels", job.split)
        ign_dir = os.path.join(root, yf.IGNORE_FOLDER, job.split)
        os.makedirs(img_dir, exist_ok=True)
        os.makedirs(lbl_dir, exist_ok=True)
        if task == "det":
            os.makedirs(ign_dir, exist_ok=True)
        for s0 in range(0, count, config.images_per_scene):
            scene_idx = s0 // config.images_per_scene
            srng = _rng(config.dataset_seed, _SCENE_STREAM, job.farm_seed, _TASK_CODE[task], scene_idx)
            scene_cfg = sample_scene_config(srng, config.variation, seed=int(srng.integers(0, 2 ** 31 - 1)),
                                            ground_margin_m=config.ground_margin_m)
            with SensorScene(farm, scene_cfg) as scene:
                camera = CameraModel(scene, cam_cfg)
                renderer = str(getattr(camera, "renderer", cam_cfg.renderer))   # after an EGL fallback
                K = camera.intrinsics().K
                for index in range(s0, min(count, s0 + config.images_per_scene)):
                    irng = _rng(config.dataset_seed, _IMAGE_STREAM, job.farm_seed, _TASK_CODE[task], index)
                    shot = sample_robot_pose(farm, task, irng, config.variation, base_T_optical)
                    pose = shot.world_T_base @ base_T_optical[shot.camera]
                    frame = camera.render(pose)
                    if task == "seg":
                        instances = segmentation_instances(frame.semantic, config.labels)
                        ious = class_ious(frame.semantic, instances)
                        finite = [x for x in ious.values() if not math.isnan(x)]
                        worst = min(finite) if finite else float("nan")
                    else:
                        bolls = boll_boxes(frame.semantic, frame.depth_m, frame.plant_id, farm, pose, K,
                                           config.labels)
                        instances = detection_instances(bolls, config.width, config.height)
                        ignored = detection_instances(bolls, config.width, config.height, ignored=True)
                        worst = float("nan")
                    rgb = apply_photometric(frame.rgb, irng, config.variation)
                    name = _image_name(job.farm_seed, index, ext)
                    _write_image(os.path.join(img_dir, name), rgb, config)
                    yf.write_label_file(os.path.join(lbl_dir, os.path.splitext(name)[0] + ".txt"),
                                        instances, task)
                    if task == "det":
                        yf.write_label_file(os.path.join(ign_dir, os.path.splitext(name)[0] + ".txt"),
                                            ignored, task)
                    yaw = math.atan2(shot.world_T_base[1, 0], shot.world_T_base[0, 0])
                    records.append(ImageRecord(
                        task, job.split, f"images/{job.split}/{name}", job.farm_seed, scene_idx, shot.camera,
                        shot.mode, float(shot.world_T_base[0, 3]), float(shot.world_T_base[1, 3]), yaw,
                        farm_cfg.growth_stage, scene_cfg.sun_azimuth_rad, scene_cfg.sun_elevation_rad,
                        len(instances), worst, renderer))
                    if on_image is not None:
                        on_image()
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


def generate_dataset(config: DatasetConfig, progress: bool = True) -> DatasetSummary:
    """Generate the whole dataset described by ``config`` (see the module docstring).

    Existing files with the same names are overwritten; other files in
    ``out_dir`` are left alone. Raises ValueError for an unusable camera
    configuration (e.g. an unknown renderer) before any rendering starts.
    """
    if not isinstance(config, DatasetConfig):
        raise ValueError(f"config must be a DatasetConfig, got {type(config).__name__}")
    config.camera_config()                     # fail early on a bad renderer / size
    jobs = plan_jobs(config)
    total = sum(j.total for j in jobs)
    t0 = time.monotonic()
    bar = _Progress(total, progress)
    records: List[ImageRecord] = []
    if config.workers == 1 or len(jobs) <= 1:
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


def parse_seed_list(text: str) -> Tuple[int, ...]:
    """'0-19', '3', '0,2,5-7' or '' -> a tuple of seeds (ValueError naming the bad part)."""
    if text is None:
        return ()
    seeds: List[int] = []
    for part in str(text).replace(" ", "").split(","):
        if not part:
            continue
        try:
            if "-" in part:
                a, b = part.split("-", 1)
                lo, hi = int(a), int(b)
                if lo > hi:
                    raise ValueError
                seeds.extend(range(lo, hi + 1))
            else:
                seeds.append(int(part))
        except ValueError:
            raise ValueError(f"bad seed list part {part!r} in {text!r}: use 'A-B', 'N' or a comma list") from None
    if any(s < 0 for s in seeds):
        raise ValueError(f"seeds must be >= 0, got {text!r}")
    return tuple(dict.fromkeys(seeds))


def parse_image_size(text: str) -> Tuple[int, int]:
    """'640x480' -> (640, 480) (ValueError for anything else)."""
    parts = str(text).lower().split("x")
    try:
        if len(parts) != 2:
            raise ValueError
        w, h = int(parts[0]), int(parts[1])
    except ValueError:
        raise ValueError(f"image size must be 'WxH' like 640x480, got {text!r}") from None
    if w < 16 or h < 16 or w > 4096 or h > 4096:
        raise ValueError(f"image size must be between 16 and 4096 px per side, got {text!r}")
    return w, h
