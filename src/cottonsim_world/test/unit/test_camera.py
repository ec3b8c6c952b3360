"""Tests of the RGB-D camera, both renderers: intrinsics, depth, projection, semantics, cloud."""
import dataclasses
import math

import numpy as np
import pytest

from cottonsim_common.testing import assert_config_rejects
from cottonsim_world.farm.model import Farm, Plant, PlantModel, Pose2D, SemanticClass, TriangleMesh
from cottonsim_world.sensors.camera import CameraConfig, CameraModel
from cottonsim_world.sensors.scene import SceneConfig, SensorScene
from cottonsim_world.sensors.standin_plants import standin_plant_model
from world_camera_poses import optical_pose


def quad_model(half_width, height, rgba=(0.2, 0.6, 0.2, 1.0)):
    """A vertical two-sided quad in the plant-local x-z plane (y = 0)."""
    v = np.array([[-half_width, 0, 0], [half_width, 0, 0], [half_width, 0, height], [-half_width, 0, height]],
                 np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]], np.int32)
    mesh = TriangleMesh(v, f, rgba, SemanticClass.PLANT)
    return PlantModel({"leaf": mesh}, [], np.zeros((0, 3)), np.zeros(0), height, 2 * half_width)


def sphere_model(centre, radius):
    from cottonsim_world.sensors.standin_plants import _sphere_mesh
    v, f = _sphere_mesh(radius, centre, rings=10, segments=16)
    mesh = TriangleMesh(v.astype(np.float32), f.astype(np.int32), (1.0, 1.0, 1.0, 1.0), SemanticClass.BOLL)
    return PlantModel({"boll": mesh}, [], np.array([centre]), np.array([radius]), centre[2] + radius, 2 * radius)


def make_farm(models_xy):
    plants = [Plant(i, 0, i, x, y, 0.0, m) for i, (m, x, y) in enumerate(models_xy)]
    return Farm(config=None, plants=plants, lanes=[], spawn=Pose2D(0.0, 0.0, 0.0))


SMALL = CameraConfig(width=160, height=120, plant_id_image=True)
RENDERERS = ("numba", "tiny")


@pytest.fixture(params=RENDERERS)
def renderer(request):
    """Each geometric check runs with the numba rasteriser and with pybullet's TinyRenderer."""
    return request.param


def small(renderer, **kw):
    return dataclasses.replace(SMALL, renderer=renderer, **kw)


def test_intrinsics_from_fov():
    cam_cfg = CameraConfig(width=640, height=480, horizontal_fov_rad=1.5184)
    with SensorScene(make_farm([])) as scene:
        intr = CameraModel(scene, cam_cfg).intrinsics()
    f = 320.0 / math.tan(0.7592)              # 87 deg h-FOV on 640 px
    assert intr.fx == pytest.approx(f) and intr.fy == pytest.approx(f)
    assert intr.fx == pytest.approx(337.2, abs=0.2)
    assert (intr.cx, intr.cy) == (319.5, 239.5)
    assert intr.K[0, 0] == intr.fx and intr.K[2, 2] == 1.0 and intr.P.shape == (3, 4)
    assert np.all(intr.P[:, 3] == 0.0)
    assert cam_cfg.vertical_fov_rad == pytest.approx(2 * math.atan(math.tan(0.7592) * 0.75))


def test_depth_of_a_plane_at_known_distance_and_cloud_geometry(renderer):
    # a wall 3 m in front of a level camera at 2.5 m height, facing +y; the
    # vertical half-FOV is 35.5 deg, so the view spans z = 0.36 .. 4.64 m on it
    farm = make_farm([(quad_model(10.0, 6.0), 0.0, 3.0)])
    with SensorScene(farm) as scene:
        cam = CameraModel(scene, small(renderer))
        pose = optical_pose(0.0, 0.0, 2.5, math.pi / 2)
        frame = cam.render(pose)
        wall = frame.semantic == SemanticClass.PLANT
        assert wall.all()                             # the wall fills the whole view
        np.testing.assert_allclose(frame.depth_m[wall], 3.0, atol=2e-3)
        assert np.all(frame.plant_id[wall] == 0)
        xyz, rgb = cam.point_cloud(frame)
        assert xyz.dtype == np.float32 and rgb.dtype == np.uint8 and len(xyz) == len(rgb)
        # back to the world: all wall points lie on the plane y = 3 and within its extent
        world = xyz @ pose[:3, :3].T + pose[:3, 3]
        assert len(xyz) == SMALL.width * SMALL.height
        np.testing.assert_allclose(world[:, 1], 3.0, atol=3e-3)
        assert world[:, 2].min() == pytest.approx(2.5 - 3.0 * math.tan(SMALL.vertical_fov_rad / 2), abs=0.05)
        # and each cloud point projects back to a pixel whose depth is its z
        intr = cam.intrinsics()
        u = np.rint(intr.fx * xyz[:, 0] / xyz[:, 2] + intr.cx).astype(int)
        v = np.rint(intr.fy * xyz[:, 1] / xyz[:, 2] + intr.cy).astype(int)
        np.testing.assert_allclose(frame.depth_m[v, u], xyz[:, 2], rtol=1e-5)


def test_ground_depth_looking_straight_down(renderer):
    with SensorScene(make_farm([])) as scene:
        cam = CameraModel(scene, small(renderer))
        frame = cam.render(optical_pose(0.0, 0.0, 2.0, 0.0, pitch_down=math.pi / 2))
    assert np.all(frame.semantic == SemanticClass.GROUND)
    np.testing.assert_allclose(frame.depth_m, 2.0, rtol=1e-5)


def test_white_sphere_appears_at_projected_pixel(renderer):
    centre_world = np.array([0.6, 4.0, 1.3])
    farm = make_farm([(sphere_model((0.6, 0.0, 1.3), 0.12), 0.0, 4.0)])
    with SensorScene(farm) as scene:
        cam = CameraModel(scene, CameraConfig(width=320, height=240, renderer=renderer))
        pose = optical_pose(0.0, 0.0, 1.0, math.pi / 2, pitch_down=0.1)
        frame = cam.render(pose)
        intr = cam.intrinsics()
    p = np.linalg.inv(pose) @ np.r_[centre_world, 1.0]
    u_exp = intr.fx * p[0] / p[2] + intr.cx
    v_exp = intr.fy * p[1] / p[2] + intr.cy
    rows, cols = np.nonzero(frame.semantic == SemanticClass.BOLL)
    assert len(rows) > 20
    assert cols.mean() == pytest.approx(u_exp, abs=0.25)      # a centred disc: its centroid is the centre
    assert rows.mean() == pytest.approx(v_exp, abs=0.25)
    assert frame.rgb[int(round(v_exp)), int(round(u_exp))].min() > 150     # white, lit
    # the sphere's nearest surface point is ~ its distance minus the radius
    assert np.nanmin(frame.depth_m[rows, cols]) == pytest.approx(p[2] - 0.12, abs=0.02)


def test_semantics_ground_sky_plant(renderer):
    model = standin_plant_model(seed=1)
    farm = make_farm([(model, 0.0, 5.0)])
    with SensorScene(farm) as scene:
        cam = CameraModel(scene, small(renderer))
        pose = optical_pose(0.0, 0.0, 0.6, math.pi / 2)        # level camera 0.6 m up
        frame = cam.render(pose)
        intr = cam.intrinsics()
    sem = frame.semantic
    assert np.all(sem[:5] == SemanticClass.SKY)               # top rows: above the horizon
    assert np.all(sem[-5:, :20] == SemanticClass.GROUND)      # bottom corner: ground
    p = np.linalg.inv(pose) @ np.array([0.0, 5.0 - 0.35, 0.6, 1.0])   # canopy front at camera height
    u = int(round(intr.fx * p[0] / p[2] + intr.cx))
    v = int(round(intr.fy * p[1] / p[2] + intr.cy))
    assert sem[v, u] in (SemanticClass.PLANT, SemanticClass.BOLL)
    assert frame.plant_id[v, u] == 0
    assert set(np.unique(sem)) <= {0, 1, 2, 3}
    # sky pixels have no depth, ground pixels have one
    assert np.all(np.isnan(frame.depth_m[sem == SemanticClass.SKY]))
    near_ground = sem[-10:] == SemanticClass.GROUND           # bottom rows: ground within far_m
    assert np.all(np.isfinite(frame.depth_m[-10:][near_ground]))


def test_frustum_culling_keeps_only_plants_in_view(renderer):
    m = standin_plant_model(seed=0, bolls=0)
    farm = make_farm([(m, 0.0, 4.0), (m, 0.0, -4.0), (m, 8.0, 0.0), (m, 0.0, 40.0)])
    with SensorScene(farm) as scene:
        cam = CameraModel(scene, CameraConfig(width=64, height=48, cull_distance_m=25.0, renderer=renderer,
                                              plant_id_image=True))
        frame = cam.render(optical_pose(0.0, 0.0, 0.5, math.pi / 2))
        assert cam.last_render_stats["plants"] == 1           # ahead; not behind, aside or too far
        assert set(np.unique(frame.plant_id)) == {-1, 0}
        if renderer == "tiny":
            assert cam._client.loaded_plants == {0}
        frame = cam.render(optical_pose(0.0, 0.0, 0.5, -math.pi / 2))  # turn around: swap bodies
        assert set(np.unique(frame.plant_id)) == {-1, 1}
        if renderer == "tiny":
            assert cam._client.loaded_plants == {1}


def test_bad_input_raises_clear_errors():
    assert_config_rejects(CameraConfig, ("horizontal_fov_rad", 4.0), ("width", 0),
                          ("renderer", "vulkan", "renderer.*numba"))
    with SensorScene(make_farm([])) as scene:
        cam = CameraModel(scene, CameraConfig(width=32, height=24))
        bad = np.eye(4)
        bad[0, 3] = np.nan
        with pytest.raises(ValueError, match="world_T_optical"):
            cam.render(bad)
        with pytest.raises(ValueError, match="4x4"):
            cam.render(np.eye(3))
