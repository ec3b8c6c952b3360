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

Modules (import from this package; the names below are its API):

* ``config``: DatasetConfig, VariationConfig, LabelConfig, the task / split /
  camera names;
* ``randomize``: sample_farm_config, sample_scene_config, apply_photometric;
* ``poses``: sample_robot_pose, base_pose_matrix, camera_transforms;
* ``seg_labels``: mask_to_label_polygons, segmentation_instances, class_ious;
* ``det_labels``: boll_boxes, detection_instances;
* ``pipeline``: plan_jobs, render_farm_job, generate_dataset (worker pool);
* ``ray_engine``: RayEngineConfig, plan_ranges, run_on_ray (Ray imported only
  when a RayEngineConfig is passed to generate_dataset);
* ``cli``: parse_seed_list, parse_image_size.
"""
from .cli import parse_image_size, parse_seed_list
from .config import (CAMERA_FRONT, CAMERA_LEFT, CAMERA_RIGHT, CAMERAS, DEFAULT_URDF_PATH, IMAGE_FORMATS, SPLITS,
                     TASKS, DatasetConfig, LabelConfig, VariationConfig)
from .det_labels import BollLabel, boll_boxes, detection_instances
from .pipeline import (DatasetSummary, EncodedImage, FarmJob, ImageRecord, generate_dataset, plan_jobs,
                       render_farm_job, render_scene_range, split_seeds, write_encoded_image)
from .ray_engine import RayEngineConfig, SceneRange, plan_ranges
from .poses import RobotShot, base_pose_matrix, camera_transforms, sample_robot_pose
from .randomize import apply_photometric, sample_farm_config, sample_scene_config, seeded_rng
from .seg_labels import (SEG_GROUND, SEG_PLANT, SEG_SKY, class_ious, mask_to_label_polygons,
                         rasterize_instances, segmentation_instances, segmentation_masks)

__all__ = [
    "CAMERA_FRONT", "CAMERA_LEFT", "CAMERA_RIGHT", "CAMERAS", "DEFAULT_URDF_PATH", "IMAGE_FORMATS", "SPLITS",
    "TASKS", "DatasetConfig", "LabelConfig", "VariationConfig",
    "sample_farm_config", "sample_scene_config", "apply_photometric", "seeded_rng",
    "RobotShot", "base_pose_matrix", "camera_transforms", "sample_robot_pose",
    "SEG_PLANT", "SEG_GROUND", "SEG_SKY", "mask_to_label_polygons", "segmentation_masks",
    "segmentation_instances", "rasterize_instances", "class_ious",
    "BollLabel", "boll_boxes", "detection_instances",
    "FarmJob", "split_seeds", "plan_jobs", "ImageRecord", "DatasetSummary", "render_farm_job",
    "generate_dataset", "EncodedImage", "render_scene_range", "write_encoded_image",
    "RayEngineConfig", "SceneRange", "plan_ranges",
    "parse_seed_list", "parse_image_size",
]
