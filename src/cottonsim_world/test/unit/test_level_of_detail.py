"""Levels of detail of the numba camera, and the compiled cloud / LiDAR packing.

What the far level promises (``fast.level_of_detail.proxy_model_arrays``):
every part keeps its mean silhouette (convex parts: their area), semantic
class and base colour with far fewer triangles; a camera draws it only where its error bound is at most
``lod_max_error_px`` pixels, so a far view keeps its plant and boll pixel counts and nearly all labels.
The middle levels (``simplified_model_arrays``): each part's fewest-face version within a surface
distance, leaves keep their area; a lane view keeps its plant and boll pixel counts within a few
per cent and ~97 % or more of its labels. Full detail (no level meets the budget) is unchanged.
"""
import dataclasses
import math

import numpy as np
import pytest

from cottonsim_world.farm.generator import FarmConfig, generate_farm
from cottonsim_world.farm.model import SemanticClass
from cottonsim_world.sensors.camera import CameraConfig, CameraModel
from cottonsim_world.sensors.fast.level_of_detail import (_fan_decimations, part_levels, proxy_model_arrays,
                                                           simplified_model_arrays)
from cottonsim_world.sensors.fast.mesh_arrays import model_arrays, pair_reversed_faces
from cottonsim_world.sensors.fast.surface_distance import point_mesh_distance, surface_distance
from cottonsim_world.sensors.lidar import LidarConfig, Vlp16Model
from cottonsim_world.sensors.scene import SensorScene
from world_camera_poses import optical_pose


def area(v, f):
    return 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum()


def uv_sphere(radius, centre, n_lon=10, n_lat=6):
    verts = [(0.0, 0.0, radius)]
    for i in range(1, n_lat):
        a = math.pi * i / n_lat
        for j in range(n_lon):
            b = 2 * math.pi * j / n_lon
            verts.append((radius * math.sin(a) * math.cos(b), radius * math.sin(a) * math.sin(b), radius * math.cos(a)))
    verts.append((0.0, 0.0, -radius))
    faces = []
    for j in range(n_lon):
        faces.append((0, 1 + j, 1 + (j + 1) % n_lon))
    for i in range(n_lat - 2):
        for j in range(n_lon):
            a, b = 1 + i * n_lon + j, 1 + i * n_lon + (j + 1) % n_lon
            faces += [(a, a + n_lon, b + n_lon), (a, b + n_lon, b)]
    last, base = len(verts) - 1, 1 + (n_lat - 2) * n_lon
    for j in range(n_lon):
        faces.append((last, base + (j + 1) % n_lon, base + j))
    return np.array(verts) + centre, np.array(faces)


def test_proxies_keep_area_class_and_colour_of_each_part():
    # three parts: a two-sided disc (flat), a sphere (solid), a long thin tube
    ang = np.linspace(0, 2 * math.pi, 13)[:-1]
    disc_v = np.vstack([[0, 0, 0.5], np.c_[0.1 * np.cos(ang), 0.05 * np.sin(ang), np.full(12, 0.5)]])
    fan = np.array([(0, 1 + j, 1 + (j + 1) % 12) for j in range(12)])
    disc_f = np.vstack([fan, fan[:, ::-1]])
    sph_v, sph_f = uv_sphere(0.03, np.array([0.2, 0.0, 0.3]))
    z = np.linspace(0.0, 0.8, 5)
    tube_v = np.array([(0.004 * math.cos(a), 0.004 * math.sin(a), zz) for zz in z for a in np.arange(6) * math.pi / 3])
    tube_f = np.array([(k * 6 + j, k * 6 + (j + 1) % 6, (k + 1) * 6 + (j + 1) % 6) for k in range(4) for j in range(6)]
                      + [(k * 6 + j, (k + 1) * 6 + (j + 1) % 6, (k + 1) * 6 + j) for k in range(4) for j in range(6)])
    v = np.vstack([disc_v, sph_v, tube_v])
    f = np.vstack([disc_f, sph_f + len(disc_v), tube_f + len(disc_v) + len(sph_v)])
    sem = np.r_[np.zeros(len(disc_f)), np.full(len(sph_f), 3), np.zeros(len(tube_f))].astype(np.uint8)
    rgb = np.vstack([np.tile([0.2, 0.5, 0.1], (len(disc_f), 1)), np.tile([0.96, 0.96, 0.94], (len(sph_f), 1)),
                     np.tile([0.4, 0.4, 0.3], (len(tube_f), 1))])
    pv, pf, psem, prgb, pn, error_m = proxy_model_arrays(v, f, sem, rgb)
    assert len(pf) == 4 + 8 + 6 < len(f)                    # rectangle (two-sided), octahedron, prism
    assert np.allclose(np.linalg.norm(pn, axis=1), 1.0)
    for cls, colour, a_full in ((SemanticClass.BOLL, (0.96, 0.96, 0.94), area(sph_v, sph_f)),):
        sel = psem == cls
        assert sel.sum() == 8 and np.allclose(prgb[sel], colour)
        assert area(pv, pf[sel]) == pytest.approx(a_full, rel=1e-9)
    green = np.all(np.isclose(prgb, [0.2, 0.5, 0.1]), axis=1)
    assert green.sum() == 4 and area(pv, pf[green]) == pytest.approx(area(disc_v, disc_f), rel=1e-9)
    assert (pair_reversed_faces(pf[green])[1] >= 0).all()     # still drawn from both sides
    brown = np.all(np.isclose(prgb, [0.4, 0.4, 0.3]), axis=1)
    assert brown.sum() == 6 and area(pv, pf[brown]) == pytest.approx(area(tube_v, tube_f), rel=1e-9)
    # the octahedron's faces point outwards
    box = pf[psem == 3]
    centre = pv[box].reshape(-1, 3).mean(axis=0)
    nrm = np.cross(pv[box[:, 1]] - pv[box[:, 0]], pv[box[:, 2]] - pv[box[:, 0]])
    assert np.all(np.einsum("ij,ij->i", nrm, pv[box].mean(axis=1) - centre) > 0)
    assert 0.2 <= error_m <= 0.3                             # the disc's diagonal (0.22 m) rules


def test_generated_plants_have_far_fewer_triangles_and_the_same_area_per_class():
    farm = generate_farm(FarmConfig(rows=1, plants_per_row=2, plant_variants=2, seed=5))
    for plant in farm.plants:
        v, f, sem, rgb, _ = model_arrays(plant.model)
        pv, pf, psem, prgb, _, error_m = proxy_model_arrays(v, f, sem, rgb)
        assert len(pf) < 0.3 * len(f)
        for cls in (SemanticClass.PLANT, SemanticClass.BOLL):
            # hull-matched proxies: a bit less than the lumpy bolls' surface, about the leaves' two sides
            assert 0.6 < area(pv, pf[psem == cls]) / area(v, f[sem == cls]) < 1.5
        assert set(map(tuple, np.round(prgb, 6))) == set(map(tuple, np.round(rgb, 6)))   # same base colours
        assert 0.0 < error_m < 0.5


@pytest.fixture(scope="module")
def farm_scene():
    farm = generate_farm(FarmConfig(rows=5, plants_per_row=8, plant_variants=2, seed=2))
    with SensorScene(farm) as scene:
        yield scene


def _pixel_agreement(a, b):
    """Relative plant / boll pixel count changes and the share of differing labels from frame a to frame b."""
    change = {}
    for cls in (SemanticClass.PLANT, SemanticClass.BOLL):
        na, nb = np.count_nonzero(a.semantic == cls), np.count_nonzero(b.semantic == cls)
        change[cls] = (na, nb)
    return change, float((a.semantic != b.semantic).mean())


def test_full_detail_views_are_unchanged_and_far_views_keep_their_pixels(farm_scene):
    full_cfg = CameraConfig(width=320, height=240, plant_id_image=True, lod_max_error_px=0.0)
    full = CameraModel(farm_scene, full_cfg)
    lod = CameraModel(farm_scene, dataclasses.replace(full_cfg, lod_max_error_px=3.0))
    tiny = CameraModel(farm_scene, dataclasses.replace(full_cfg, lod_max_error_px=1e-6))
    lane = farm_scene.farm.lanes[1]
    mid = 0.5 * (lane.y_start_m + lane.y_end_m)
    # beside a plant, looking at the next row 0.9 m away; an error budget no level meets draws all at full detail
    near = optical_pose(lane.x_m, mid, 0.5, math.pi, math.radians(10))
    a, b = full.render(near), tiny.render(near)
    assert tiny.last_render_stats["middle"] == tiny.last_render_stats["simplified"] == 0
    for name in ("rgb", "depth_m", "semantic", "plant_id"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    # the whole farm from 12 m: plants 12-18 m away, all simplified
    far = optical_pose(lane.x_m, lane.y_start_m - 12.0, 0.5, math.pi / 2, math.radians(2))
    a, b = full.render(far), lod.render(far)
    assert lod.last_render_stats["simplified"] == lod.last_render_stats["plants"] > 10
    for cls in (SemanticClass.PLANT, SemanticClass.BOLL):
        na, nb = np.count_nonzero(a.semantic == cls), np.count_nonzero(b.semantic == cls)
        assert na > 20 and abs(nb - na) <= 0.1 * na + 5, cls
    plants = (a.plant_id >= 0) | (b.plant_id >= 0)
    assert (a.semantic == b.semantic).mean() >= 0.99
    # each plant keeps its size on screen (which of a far plant's ~10 px are hit is a sampling lottery)
    ids = np.unique(a.plant_id[a.plant_id >= 0])
    per_a = np.array([np.count_nonzero(a.plant_id == i) for i in ids])
    per_b = np.array([np.count_nonzero(b.plant_id == i) for i in ids])
    assert len(ids) > 10 and np.abs(per_b - per_a).sum() <= 0.25 * per_a.sum()
    both = np.isfinite(a.depth_m) & np.isfinite(b.depth_m) & plants
    assert np.median(np.abs(a.depth_m[both] - b.depth_m[both])) < 0.05


@pytest.mark.parametrize("width", [320, 640])
def test_middle_levels_keep_plant_and_boll_pixels_in_a_lane(farm_scene, width):
    # the robot's cameras in a lane: along the rows (front) and at the hedge 0.9 m away (side), where
    # most plants in view are drawn with a middle level
    full_cfg = CameraConfig(width=width, height=width * 3 // 4, plant_id_image=True, lod_max_error_px=0.0)
    full = CameraModel(farm_scene, full_cfg)
    lod = CameraModel(farm_scene, dataclasses.replace(full_cfg, lod_max_error_px=4.0))
    lane = farm_scene.farm.lanes[1]
    counts = np.zeros((2, 2))
    differ, middle = [], 0
    for yaw, pitch in ((math.pi / 2, 5.0), (math.pi, 15.0), (0.0, 15.0)):
        pose = optical_pose(lane.x_m, lane.y_start_m + 0.5, 0.55, yaw, math.radians(pitch))
        a, b = full.render(pose), lod.render(pose)
        middle += lod.last_render_stats["middle"]
        change, share = _pixel_agreement(a, b)
        counts += [change[SemanticClass.PLANT], change[SemanticClass.BOLL]]
        differ.append(share)
        both = np.isfinite(a.depth_m) & np.isfinite(b.depth_m) & (a.plant_id >= 0) & (b.plant_id >= 0)
        assert np.median(np.abs(a.depth_m[both] - b.depth_m[both])) < 0.01
    assert middle > 10
    (plant_a, plant_b), (boll_a, boll_b) = counts
    assert boll_a > 300 and abs(boll_b - boll_a) <= 0.05 * boll_a, (boll_a, boll_b)
    assert abs(plant_b - plant_a) <= 0.03 * plant_a, (plant_a, plant_b)
    assert max(differ) <= 0.03, differ


def test_middle_levels_stay_within_their_tolerance_with_fewer_faces():
    farm = generate_farm(FarmConfig(rows=1, plants_per_row=1, plant_variants=1, seed=5))
    v, f, sem, rgb, _ = model_arrays(farm.plants[0].model)
    versions = part_levels(v, f, 0.025)
    drawn = len(pair_reversed_faces(f)[0])
    previous = drawn
    for tol in (0.01, 0.025):
        mv, mf, msem, mrgb, mn, error_m = simplified_model_arrays(v, f, sem, rgb, tol, versions)
        now = len(pair_reversed_faces(mf)[0])
        assert 0.0 < error_m <= tol and now < 0.8 * previous
        previous = now
        assert np.allclose(np.linalg.norm(mn, axis=1), 1.0)
        assert set(map(tuple, np.round(mrgb, 6))) == set(map(tuple, np.round(rgb, 6)))
        for cls in (SemanticClass.PLANT, SemanticClass.BOLL):
            # leaves keep their one-sided area; bolls and tubes their convex hull's / lateral area
            assert 0.8 < area(mv, mf[msem == cls]) / area(v, f[sem == cls]) < 1.05, (tol, cls)
    assert previous < 0.5 * drawn


def test_fan_decimations_keep_the_area_and_the_surface_distance_is_a_distance():
    # a two-sided fan: a hub and an open zig-zag outline (tips and notches)
    ang = np.linspace(-1.2, 1.2, 9)
    radius = np.where(np.arange(9) % 2 == 0, 0.1, 0.07)
    v = np.vstack([[0.0, 0.0, 0.0], np.c_[radius * np.cos(ang), radius * np.sin(ang), np.zeros(9)]])
    fan = np.array([(0, 1 + j, 2 + j) for j in range(8)])
    f = np.vstack([fan, fan[:, ::-1]])
    steps = _fan_decimations(v, f, max_step_m=1.0)
    assert [len(sf) for _, sf in steps] == [14, 12, 10, 8, 6, 4]          # down to two triangles, two-sided
    for sv, sf in steps:
        assert area(sv, sf) == pytest.approx(area(v, f), rel=1e-9)
        assert np.array_equal(sv[0], v[0])                                  # the hub stays
    errors = [surface_distance(v, f, sv, sf) for sv, sf in steps]
    assert 0.0 < errors[0] < errors[-1] < 0.1
    assert _fan_decimations(v, f, max_step_m=1e-4) == []
    assert _fan_decimations(v, fan, max_step_m=1.0) == []                  # one-sided: not a leaf blade
    # a square and the same square 1 cm above it: 1 cm apart; a point's distance to a triangle
    sq = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    quad = np.array([(0, 1, 2), (0, 2, 3)])
    assert surface_distance(sq, quad, sq + [0, 0, 0.01], quad) == pytest.approx(0.01, abs=1e-12)
    pts = np.array([[0.5, 0.2, 0.3], [2.0, 0.5, 0.0], [-1.0, -1.0, 1.0]])
    np.testing.assert_allclose(point_mesh_distance(pts, sq[quad]), [0.3, 1.0, math.sqrt(3.0)], rtol=1e-12)


def test_lod_config_is_validated():
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="lod_max_error_px"):
            CameraConfig(lod_max_error_px=bad)


@pytest.mark.parametrize("stride", [1, 3])
def test_point_cloud_matches_a_numpy_back_projection(farm_scene, stride):
    cam = CameraModel(farm_scene, CameraConfig(width=160, height=120, cloud_stride=stride, cloud_max_m=6.0))
    lane = farm_scene.farm.lanes[1]
    frame = cam.render(optical_pose(lane.x_m, lane.y_start_m - 1.0, 0.55, math.pi / 2, math.radians(5)))
    xyz, rgb = cam.point_cloud(frame)
    intr = cam.intrinsics()
    z = frame.depth_m[::stride, ::stride]
    with np.errstate(invalid="ignore"):
        rows, cols = np.nonzero((z >= 0.105) & (z <= 6.0))
    assert 0 < len(rows) < z.size                              # some pixels are sky or too far
    zk = z[rows, cols]
    np.testing.assert_allclose(xyz[:, 2], zk)
    np.testing.assert_allclose(xyz[:, 0], (cols * stride - intr.cx) / intr.fx * zk, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(xyz[:, 1], (rows * stride - intr.cy) / intr.fy * zk, rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(rgb, frame.rgb[::stride, ::stride][rows, cols])
    with pytest.raises(ValueError, match="shape"):
        cam.point_cloud(dataclasses.replace(frame, rgb=frame.rgb[:10]))


def test_lidar_scan_packs_what_ranges_reports(farm_scene):
    cfg = LidarConfig(noise_std_m=0.01, seed=7, samples_per_ring=300)
    lidar, twin = Vlp16Model(farm_scene, cfg), Vlp16Model(farm_scene, cfg)
    lane = farm_scene.farm.lanes[1]
    pose = np.eye(4)
    pose[:3, 3] = (lane.x_m, lane.y_start_m + 1.0, 0.62)
    scan = lidar.scan(pose)
    rng_m, sem, pid = twin.ranges(pose)                        # the noise-free ranges of the same rays
    noise = np.random.default_rng(7).normal(0.0, 0.01, len(rng_m))
    noisy = rng_m + noise
    with np.errstate(invalid="ignore"):
        keep = np.isfinite(rng_m) & (noisy >= cfg.min_range_m) & (noisy <= cfg.max_range_m)
    assert keep.sum() == len(scan.points) > 100
    assert (sem[keep] == SemanticClass.PLANT).any() and (sem[keep] == SemanticClass.GROUND).any()
    np.testing.assert_array_equal(scan.semantic, sem[keep])
    np.testing.assert_array_equal(scan.plant_id, pid[keep])
    np.testing.assert_allclose(np.linalg.norm(scan.points, axis=1), noisy[keep], rtol=1e-6)
    assert scan.points.dtype == np.float32 and scan.intensity.dtype == np.float32
    assert np.all(scan.intensity[scan.semantic == SemanticClass.GROUND]
                  == np.float32(cfg.reflectivity[SemanticClass.GROUND] * 100.0))


def test_packed_cloud_and_its_message_match_the_unpacked_ones(farm_scene):
    import rospy
    from cottonsim_common.ros import conversions as conv
    from cottonsim_world.ros.bridge_node import packed_xyzrgb_cloud_msg

    cam = CameraModel(farm_scene, CameraConfig(width=160, height=120, cloud_stride=2))
    lane = farm_scene.farm.lanes[1]
    frame = cam.render(optical_pose(lane.x_m, lane.y_start_m - 1.0, 0.55, math.pi / 2, math.radians(5)))
    xyz, rgb = cam.point_cloud(frame)
    packed, colours = cam.point_cloud_xyzrgb(frame)
    np.testing.assert_array_equal(colours, rgb)
    assert packed.shape == (len(xyz), 4) and packed.dtype == np.float32 and len(xyz) > 100
    np.testing.assert_array_equal(packed[:, :3], xyz)
    colour = packed[:, 3].view(np.uint32)
    np.testing.assert_array_equal(colour >> 16, rgb[:, 0])
    np.testing.assert_array_equal((colour >> 8) & 255, rgb[:, 1])
    np.testing.assert_array_equal(colour & 255, rgb[:, 2])
    stamp = rospy.Time(12, 5)
    a = packed_xyzrgb_cloud_msg(packed, stamp, "cam")
    b = conv.xyzrgb_cloud_msg(xyz, rgb, stamp, "cam")
    assert a.data == b.data and a.fields == b.fields and a.point_step == b.point_step == 16
    assert (a.width, a.height, a.row_step, a.is_dense, a.header.frame_id) == (b.width, b.height, b.row_step,
                                                                              b.is_dense, b.header.frame_id)
    with pytest.raises(ValueError, match="packed cloud"):
        packed_xyzrgb_cloud_msg(xyz, stamp, "cam")


def test_camera_kernels_release_the_gil_and_render_alike_in_threads(farm_scene):
    # the simulator may run the sensor kernels in a worker thread next to the physics: they must not hold the GIL
    import threading

    from cottonsim_world.sensors.fast import image_compose, raster

    for kernel in (raster.draw_plants, raster._clip_near_and_draw, image_compose.compose_image,
                   image_compose.fill_cloud_xyzrgb):
        assert kernel.targetoptions.get("nogil") is True, kernel
    cams = [CameraModel(farm_scene, CameraConfig(width=160, height=120)) for _ in range(2)]
    lane = farm_scene.farm.lanes[1]
    poses = [optical_pose(lane.x_m, lane.y_start_m + 0.5 + k, 0.55, math.pi / 2, 0.1) for k in range(2)]
    serial = [cam.render(pose) for cam, pose in zip(cams, poses)]
    threaded = [None, None]

    def work(k):
        for _ in range(3):
            threaded[k] = cams[k].render(poses[k])

    threads = [threading.Thread(target=work, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(serial, threaded):
        np.testing.assert_array_equal(a.semantic, b.semantic)
        np.testing.assert_array_equal(a.rgb, b.rgb)
