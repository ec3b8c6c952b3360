"""Boll-detection labels: the visible bolls of a rendered frame -> YOLO boxes and ignore boxes.

``boll_boxes`` finds which pixels of the rendered semantic / depth / plant-id
images belong to which boll of the farm and returns one box per visible boll;
the bolls that miss ``LabelConfig``'s rules (working range, visible pixels and
fraction, box size) come back as ignore boxes. ``detection_instances`` turns
them into YOLO box lines (class 0 cotton boll). Boxes are in pixel-edge
coordinates as in ``yolo_format``. No ROS imports.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

from cottonsim_perception.data import yolo_format as yf
from cottonsim_world.farm.model import Farm, SemanticClass

from .config import LabelConfig


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
