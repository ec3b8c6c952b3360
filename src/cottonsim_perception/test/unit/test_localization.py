"""Pure helpers of the Cotton-Eye nodes: labels, oracle boxes, boll 3-D positions, reach."""

import numpy as np
import pytest

from cottonsim_perception.localization import (UNLABELLED, BollLocalizationConfig, boxes_from_semantic,
                                               colorize_labels, label_image_from_detections,
                                               label_image_from_masks, localize_boxes, points_within_reach,
                                               project_points)
from cottonsim_perception.types import Detections

FX = FY = 100.0
CX, CY = 49.5, 39.5            # pixel-index principal point of a 100 x 80 image (CameraInfo convention)
K = [FX, 0.0, CX, 0.0, FY, CY, 0.0, 0.0, 1.0]


def organized_cloud(depth):
    """Every pixel's back-projected point, like the simulator's cloud (row-major)."""
    h, w = depth.shape
    v, u = np.mgrid[0:h, 0:w].astype(float)
    x = (u - CX) / FX * depth
    y = (v - CY) / FY * depth
    return np.stack([x, y, depth], axis=-1).reshape(-1, 3)


def test_label_image_from_masks_orders_and_leaves_unlabelled():
    g = np.zeros((4, 5), bool); g[2:] = True
    p = np.zeros((4, 5), bool); p[1:3, 1] = True
    labels = label_image_from_masks({1: g, 0: p}, (4, 5))
    assert labels[3, 4] == 1 and labels[2, 1] == 0 and labels[1, 1] == 0   # plant over ground
    assert labels[0, 0] == UNLABELLED
    with pytest.raises(ValueError, match="class 1"):
        label_image_from_masks({1: np.zeros((3, 3), bool)}, (4, 5))


def test_label_image_from_detections_higher_score_wins():
    m = np.zeros((2, 3, 4), bool)
    m[0, :, :2] = True          # class 1 (ground), score 0.9
    m[1, :, 1:] = True          # class 2 (sky), score 0.5: overlaps column 1
    dets = Detections(np.zeros((2, 4), np.float32), np.array([0.9, 0.5], np.float32),
                      np.array([1, 2], np.int64), m)
    labels = label_image_from_detections(dets, (3, 4))
    assert labels[:, 0].tolist() == [1, 1, 1] and labels[:, 1].tolist() == [1, 1, 1]
    assert labels[:, 3].tolist() == [2, 2, 2]
    with pytest.raises(ValueError, match="masks is None"):
        label_image_from_detections(Detections.empty(), (3, 4))


def test_colorize_keeps_unlabelled_pixels():
    labels = np.array([[1, UNLABELLED]], np.uint8)
    rgb = np.full((1, 2, 3), 10, np.uint8)
    out = colorize_labels(labels, rgb, alpha=1.0)
    assert out[0, 1].tolist() == [10, 10, 10] and out[0, 0].tolist() != [10, 10, 10]
    with pytest.raises(ValueError):
        colorize_labels(labels, np.zeros((2, 2, 3), np.uint8))


def test_boxes_from_semantic_components_in_pixel_edges():
    sem = np.full((20, 30), 1, np.uint8)
    sem[2:5, 3:7] = 3           # 12 px
    sem[10:12, 20:21] = 3       # 2 px: below min_area_px = 4
    sem[15:19, 25:30] = 3       # 20 px, touching the right edge
    boxes = boxes_from_semantic(sem, 3, min_area_px=4)
    assert boxes.dtype == np.float32
    assert boxes.tolist() == [[25, 15, 30, 19], [3, 2, 7, 5]]        # largest first, (x0, y0, x1, y1)
    assert boxes_from_semantic(np.zeros((5, 5), np.uint8)).shape == (0, 4)
    with pytest.raises(ValueError, match="min_area_px"):
        boxes_from_semantic(sem, 3, min_area_px=0)


def test_projection_inverts_the_back_projection():
    depth = np.full((80, 100), 2.0)
    uv = project_points(organized_cloud(depth), FX, FY, CX, CY).reshape(80, 100, 2)
    assert uv[0, 0].tolist() == pytest.approx([0.5, 0.5])           # pixel centre in edge coordinates
    assert uv[79, 99].tolist() == pytest.approx([99.5, 79.5])


def test_localize_box_is_the_median_of_its_front_points():
    depth = np.full((80, 100), 3.0)      # a wall 3 m away (the next row, seen through a gap)
    depth[20:40, 60:80] = 1.0            # a boll-like patch 1 m away, covering most of the box
    box = np.array([[58.0, 18.0, 82.0, 42.0]])
    flat = BollLocalizationConfig(box_shrink_fraction=0.0, surface_to_centre=False)   # a flat patch: no centre
    pos, valid = localize_boxes(box, organized_cloud(depth), K, flat)
    assert valid.tolist() == [True]
    # hand value: centre pixel column 69.5 +- -> x = (69.5 - 49.5) / 100 * 1 m = 0.2 m (median of 60..79)
    assert pos[0] == pytest.approx([0.2, (29.5 - 39.5) / 100.0, 1.0], abs=1e-9)
    # without the front-surface rule the wall points (28 % of the box) still leave the median on the
    # patch, but a box mostly over the wall is pulled back: the rule keeps the patch
    big = np.array([[50.0, 10.0, 90.0, 50.0]])                    # patch is 25 % of this box
    p_front, _ = localize_boxes(big, organized_cloud(depth), K, flat)
    p_all, _ = localize_boxes(big, organized_cloud(depth), K,
                              BollLocalizationConfig(box_shrink_fraction=0.0, front_depth_m=10.0,
                                                     surface_to_centre=False))
    assert p_front[0, 2] == pytest.approx(1.0) and p_all[0, 2] == pytest.approx(3.0)


def sphere_depth(centre, radius_m, background_m=3.0, shape=(80, 100)):
    """Depth image of a sphere (optical frame) in front of a wall: each pixel's ray hits the sphere's near side."""
    h, w = shape
    v, u = np.mgrid[0:h, 0:w].astype(float)
    rays = np.stack([(u - CX) / FX, (v - CY) / FY, np.ones_like(u)], axis=-1)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    c = np.asarray(centre, dtype=float)
    along = rays @ c
    miss = along ** 2 - (c @ c - radius_m ** 2)
    hit = miss >= 0.0
    rng = np.where(hit, along - np.sqrt(np.where(hit, miss, 0.0)), np.inf)
    depth = np.where(hit, rng * rays[..., 2], background_m)
    return depth


@pytest.mark.parametrize("centre", [(0.1, 0.05, 0.9), (-0.2, 0.1, 1.2), (0.0, 0.0, 0.6)])
def test_a_boll_is_localised_at_its_centre_not_on_its_visible_surface(centre):
    """A 6 cm sphere: the median of its visible surface lies ~2 cm in front of its centre; moved along the
    ray by the box's radius it lands within 5 mm of the centre (this coarse camera: a pixel is 6-12 mm there)."""
    radius = 0.03
    depth = sphere_depth(centre, radius)
    c = np.asarray(centre)
    uv = project_points(np.array([c - [radius, radius, 0.0], c + [radius, radius, 0.0]]), FX, FY, CX, CY)
    box = np.array([[uv[0, 0], uv[0, 1], uv[1, 0], uv[1, 1]]])    # the boll's tight box
    surface, _ = localize_boxes(box, organized_cloud(depth), K, BollLocalizationConfig(surface_to_centre=False))
    centred, valid = localize_boxes(box, organized_cloud(depth), K)
    assert valid.tolist() == [True]
    assert np.linalg.norm(surface[0] - c) > 0.015
    assert np.linalg.norm(centred[0] - c) < 0.005
    with pytest.raises(ValueError, match="surface_to_centre"):
        BollLocalizationConfig(surface_to_centre="yes")


def test_a_leaf_in_front_of_a_boll_takes_the_front_surface_unless_the_lint_colour_picks_the_boll():
    """A 6 cm white sphere 0.9 m away, its left half behind a green leaf 5 cm in front: the box's front
    surface is the leaf (over 2 cm off, the nozzle's capture radius); with the lint colour test the boll's
    visible half puts it within 1 cm of its centre (the half's own centroid is off to its side)."""
    radius, centre = 0.03, np.array([0.05, 0.02, 0.9])
    depth = sphere_depth(tuple(centre), radius)
    h, w = depth.shape
    image = np.zeros((h, w, 3), np.uint8)
    image[np.isfinite(depth) & (depth < 2.0)] = (235, 232, 225)          # lint
    uv = project_points(np.array([centre - [radius, radius, 0.0], centre + [radius, radius, 0.0]]), FX, FY, CX, CY)
    box = np.array([[uv[0, 0], uv[0, 1], uv[1, 0], uv[1, 1]]])
    leaf_cols = slice(int(uv[0, 0]), int((uv[0, 0] + uv[1, 0]) / 2))
    leaf_rows = slice(int(uv[0, 1]), int(uv[1, 1]) + 1)
    depth[leaf_rows, leaf_cols] = centre[2] - 0.05
    image[leaf_rows, leaf_cols] = (40, 150, 40)
    plain, _ = localize_boxes(box, organized_cloud(depth), K, BollLocalizationConfig(lint_colour=False), image)
    lint, valid = localize_boxes(box, organized_cloud(depth), K, BollLocalizationConfig(), image)     # default on
    assert valid.tolist() == [True]
    assert np.linalg.norm(plain[0] - centre) > 0.02                   # on the leaf
    assert np.linalg.norm(lint[0] - centre) < 0.01
    no_image, _ = localize_boxes(box, organized_cloud(depth), K, BollLocalizationConfig())
    np.testing.assert_allclose(no_image, plain)                       # without an image: as before
    with pytest.raises(ValueError, match="lint_min_value"):
        BollLocalizationConfig(lint_min_value=300)
    with pytest.raises(ValueError, match="image_rgb"):
        localize_boxes(box, organized_cloud(depth), K, BollLocalizationConfig(lint_colour=True), image[..., 0])


def test_localize_handles_empty_nan_and_decimated_clouds():
    depth = np.full((80, 100), 2.0)
    cloud = organized_cloud(depth)
    cloud[::2] = np.nan
    boxes = np.array([[10.0, 10.0, 20.0, 20.0], [99.0, 79.0, 100.0, 80.0]])
    pos, valid = localize_boxes(boxes, cloud[::3], K, BollLocalizationConfig(min_points=3, surface_to_centre=False))
    assert valid.tolist() == [True, False] and np.isnan(pos[1]).all()
    assert pos[0, 2] == pytest.approx(2.0)
    pos, valid = localize_boxes(boxes, np.zeros((0, 3)), K)
    assert not valid.any()
    with pytest.raises(ValueError, match="camera matrix"):
        localize_boxes(boxes, cloud, [0.0] * 9)
    with pytest.raises(ValueError, match="min_points"):
        BollLocalizationConfig(min_points=0)
    with pytest.raises(ValueError, match="max_depth_m"):
        BollLocalizationConfig(min_depth_m=2.0, max_depth_m=1.0)


def test_reach():
    inside = points_within_reach(np.array([[0.5, 0.5, 0.3], [0.6, 0.6, 0.1], [np.nan] * 3]), 0.85)
    assert inside.tolist() == [True, False, False]                   # |(.5,.5,.3)| = 0.768, |(.6,.6,.1)| = 0.854
    with pytest.raises(ValueError, match="reach_m"):
        points_within_reach(np.zeros((1, 3)), 0.0)
