"""Configuration of a dataset generation run: what to render, how to vary it, how to label it.

``DatasetConfig`` (one run) holds a ``VariationConfig`` (what varies between
farms, scenes and images) and a ``LabelConfig`` (how labels are derived from
the rendered ground truth). Every field is validated on construction with a
ValueError that names it. No ROS imports.
"""
from __future__ import annotations

import math
import os
import pathlib
from dataclasses import dataclass, field
from typing import Optional, Tuple


from cottonsim_common.validation import require_instance, require_int, require_min_max, require_number
from cottonsim_world.farm.config import FarmConfig

TASKS = ("seg", "det")
SPLITS = ("train", "val", "test")
IMAGE_FORMATS = ("jpg", "png")

CAMERA_FRONT = "realsense_p"
CAMERA_LEFT = "realsense_secondary"
CAMERA_RIGHT = "realsense_tertiary"
CAMERAS = (CAMERA_FRONT, CAMERA_LEFT, CAMERA_RIGHT)

#: The robot's URDF in this workspace (src/cottonsim_description/urdf/).
DEFAULT_URDF_PATH = str(pathlib.Path(__file__).resolve().parents[5]
                        / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf")


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
        require_number("polygon_epsilon_px", self.polygon_epsilon_px, 0.0, 10.0)
        require_number("min_region_area_px", self.min_region_area_px, 0.0, 1e6)
        require_number("min_hole_area_px", self.min_hole_area_px, 0.0, 1e6)
        if self.seg_instances not in ("class", "region"):
            raise ValueError(f"LabelConfig.seg_instances must be 'class' or 'region', "
                             f"got {self.seg_instances!r}")
        require_number("boll_extent_factor", self.boll_extent_factor, 1.0, 5.0)
        require_number("boll_depth_tolerance_m", self.boll_depth_tolerance_m, 0.0, 1.0)
        require_number("min_boll_box_px", self.min_boll_box_px, 0.0, 1e4)
        require_int("min_boll_visible_px", self.min_boll_visible_px, 1)
        require_number("min_boll_visible_fraction", self.min_boll_visible_fraction, 0.0, 1.0)
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
            pair = require_min_max(name, getattr(self, name), lo, hi)
            if name in ("bolls_min_range", "bolls_span_range"):
                if any(not float(v).is_integer() for v in pair):
                    raise ValueError(f"{name} must hold integers, got {getattr(self, name)!r}")
                pair = (int(pair[0]), int(pair[1]))
            object.__setattr__(self, name, pair)
        if self.bolls_min_range[1] + self.bolls_span_range[1] > 60:
            raise ValueError("bolls_min_range max + bolls_span_range max must be <= 60 bolls per plant")
        for name in ("defoliated_probability", "headland_probability", "front_close_probability"):
            require_number(name, getattr(self, name), 0.0, 1.0)
        for name in ("light_tint_max", "soil_tint_max", "white_balance_max"):
            require_number(name, getattr(self, name), 0.0, 0.5)
        for name in ("camera_height_std_m", "camera_pitch_std_rad", "camera_roll_std_rad",
                     "lane_offset_std_m", "yaw_std_rad"):
            require_number(name, getattr(self, name), 0.0, 1.0)
        require_number("headland_yaw_max_rad", self.headland_yaw_max_rad, 0.0, math.pi)
        require_number("close_yaw_max_rad", self.close_yaw_max_rad, 0.0, math.pi / 2)


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
        require_int("images_per_task", self.images_per_task, 0)
        for name in ("seeds", "test_seeds"):
            seq = getattr(self, name)
            if isinstance(seq, (str, bytes)) or not hasattr(seq, "__iter__"):
                raise ValueError(f"{name} must be a sequence of integers, got {seq!r}")
            vals = tuple(require_int(f"{name} entry", s, 0) for s in seq)
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
        require_int("test_images_per_task", self.test_images_per_task, 0)
        if self.test_images_per_task > 0 and not self.test_seeds:
            raise ValueError("test_images_per_task > 0 needs test_seeds (held-out farms)")
        require_number("val_fraction", self.val_fraction, 0.0, 0.9)
        if self.val_fraction > 0.0 and self.images_per_task > 0 and len(self.seeds) < 2:
            raise ValueError("val_fraction > 0 needs at least 2 seeds (val farms are kept apart from "
                             "train farms); give more seeds or set val_fraction to 0")
        for name in ("width", "height"):
            v = require_int(name, getattr(self, name), 16)
            if v > 4096:
                raise ValueError(f"{name} must be <= 4096 px, got {v}")
        if self.horizontal_fov_rad is not None:
            require_number("horizontal_fov_rad", self.horizontal_fov_rad, 1e-3, math.pi - 1e-3)
        if self.renderer is not None and not isinstance(self.renderer, str):
            raise ValueError(f"renderer must be a string or None, got {self.renderer!r}")
        require_int("workers", self.workers, 1)
        if self.image_format not in IMAGE_FORMATS:
            raise ValueError(f"image_format must be one of {IMAGE_FORMATS}, got {self.image_format!r}")
        q = require_int("jpeg_quality", self.jpeg_quality, 1)
        if q > 100:
            raise ValueError(f"jpeg_quality must be in [1, 100], got {q}")
        require_int("images_per_scene", self.images_per_scene, 1)
        require_int("dataset_seed", self.dataset_seed, 0)
        for name, cls in (("base_farm", FarmConfig), ("variation", VariationConfig), ("labels", LabelConfig)):
            require_instance(name, getattr(self, name), cls)
        require_number("ground_margin_m", self.ground_margin_m, 0.0, 1000.0)
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
