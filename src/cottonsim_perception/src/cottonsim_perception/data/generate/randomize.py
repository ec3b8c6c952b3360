"""Random draws of a dataset: per-farm layout, per-scene light / soil / sky, per-image photometry.

Every draw comes from a generator seeded by a tuple of integers
(``seeded_rng``): (dataset_seed, stream, farm seed, task, index), so what an
image looks like does not depend on the order or process it is made in.
No ROS imports.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from cottonsim_world.farm.config import FarmConfig

from .config import VariationConfig

def seeded_rng(*key: int) -> np.random.Generator:
    """A generator from a tuple of non-negative ints (order-sensitive, independent streams)."""
    return np.random.default_rng(np.random.SeedSequence([int(k) for k in key]))


#: Task and stream codes in the seed tuples of ``seeded_rng``.
TASK_CODE = {"seg": 1, "det": 2}
FARM_STREAM, SCENE_STREAM, IMAGE_STREAM = 11, 12, 13


def sample_farm_config(base: FarmConfig, farm_seed: int, variation: VariationConfig,
                       dataset_seed: int = 0) -> FarmConfig:
    """The FarmConfig of one farm: ``base`` with its seed set to ``farm_seed``
    and the per-farm ranges of ``variation`` drawn from (dataset_seed, farm_seed).

    The position jitter is capped so the lanes keep the robot's clearance.
    """
    rng = seeded_rng(dataset_seed, FARM_STREAM, farm_seed)
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
