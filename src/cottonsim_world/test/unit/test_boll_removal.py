"""A boll that leaves its plant vanishes from the camera (colour, depth, cloud, masks) and the LiDAR at once,
on every backend; its twin on another plant of the same model stays; the split keeps every triangle."""
import math

import numpy as np
import pytest

from cottonsim_world.farm.bolls import BollField
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.farm.model import Farm, Plant, Pose2D, SemanticClass
from cottonsim_world.sensors.boll_instances import SplitFarm
from cottonsim_world.sensors.camera import CameraConfig, CameraModel
from cottonsim_world.sensors.lidar import LidarConfig, Vlp16Model
from cottonsim_world.sensors.scene import SensorScene
from cottonsim_world.sensors.standin_plants import standin_plant_model
from world_camera_poses import optical_pose

BOLLS = 6
MODEL = standin_plant_model(seed=3, bolls=BOLLS)   # white spheres half out of a green canopy cylinder
TWIN_OFFSET_Y_M = 3.0


@pytest.fixture(scope="module")
def farm():
    """Two plants sharing one model, 3 m apart along y."""
    plants = [Plant(0, 0, 0, 0.0, 0.0, 0.0, MODEL), Plant(1, 0, 1, 0.0, TWIN_OFFSET_Y_M, 0.0, MODEL)]
    return Farm(config=None, plants=plants, lanes=[], spawn=Pose2D(-5.0, 0.0, 0.0))


def facing(centre, distance_m):
    """(position, yaw) of a sensor ``distance_m`` out from the stem beyond ``centre``, looking at it."""
    out = np.array([centre[0], centre[1] - round(centre[1] / TWIN_OFFSET_Y_M) * TWIN_OFFSET_Y_M])
    out /= np.linalg.norm(out)
    pos = np.array([centre[0] + distance_m * out[0], centre[1] + distance_m * out[1], centre[2]])
    return pos, math.atan2(-out[1], -out[0])


def hidden_mask(count, *ids):
    mask = np.zeros(count, bool)
    mask[list(ids)] = True
    return mask


def disc(shape, u, v, radius_px):
    rows, cols = np.mgrid[:shape[0], :shape[1]]
    return (cols - u) ** 2 + (rows - v) ** 2 <= radius_px ** 2


def boll_view(cam, centre, radius_m):
    """The camera pose 0.6 m out from the boll, looking at it, and the boll's disc in the image."""
    pos, yaw = facing(centre, 0.6)
    pose = optical_pose(*pos, yaw)
    intr = cam.intrinsics()
    return pose, disc((intr.height, intr.width), intr.cx, intr.cy, 0.6 * radius_m * intr.fx / 0.6)


@pytest.mark.parametrize("renderer", ["numba", "tiny"])
def test_camera_loses_the_boll_and_keeps_its_twin(farm, renderer):
    field = BollField(farm)
    target, twin = field.get(1), field.get(BOLLS + 1)        # boll 1 of plant 0 and of plant 1 (no neighbour near)
    assert (twin.plant_id, twin.index_on_plant) == (1, 1)
    with SensorScene(farm) as scene:
        cam = CameraModel(scene, CameraConfig(width=160, height=120, plant_id_image=True, renderer=renderer))
        pose, spot = boll_view(cam, target.position_m, target.diameter_m / 2)
        twin_pose, _ = boll_view(cam, twin.position_m, twin.diameter_m / 2)
        before, twin_before = cam.render(pose), cam.render(twin_pose)
        assert np.all(before.semantic[spot] == SemanticClass.BOLL)
        assert np.all(before.rgb[spot].min(axis=1) > 180)                    # white locks
        field.detach(1, "nozzle")
        scene.set_hidden_bolls(field.off_plant_mask(), field.revision)
        after, twin_after = cam.render(pose), cam.render(twin_pose)
        # the boll's pixels show the green canopy behind it now: class, colour, plant id and depth
        assert not np.any(after.semantic[spot] == SemanticClass.BOLL)
        assert np.all(after.semantic[spot] == SemanticClass.PLANT) and np.all(after.plant_id[spot] == 0)
        assert np.all(after.rgb[spot][:, 1] > after.rgb[spot][:, 0])          # green over red
        assert np.all(after.depth_m[spot] > before.depth_m[spot] + 0.01)
        assert np.count_nonzero(after.semantic == SemanticClass.BOLL) < np.count_nonzero(
            before.semantic == SemanticClass.BOLL)
        # the depth cloud: no point on the boll's surface outside the canopy (radius 0.35 m) any more
        def near_boll(frame):
            xyz, _ = cam.point_cloud(frame)
            world = xyz @ pose[:3, :3].T + pose[:3, 3]
            on_sphere = np.linalg.norm(world - np.array(target.position_m), axis=1) < target.diameter_m / 2 + 0.003
            return np.count_nonzero(on_sphere & (np.hypot(world[:, 0], world[:, 1]) > 0.355))
        assert near_boll(before) > 20 and near_boll(after) == 0
        # the same boll of the other plant (same model) is untouched
        assert np.array_equal(twin_before.rgb, twin_after.rgb)
        assert np.array_equal(twin_before.semantic, twin_after.semantic)
        # shown again: the first image exactly
        scene.set_hidden_bolls(np.zeros(field.count, bool))
        assert np.array_equal(cam.render(pose).rgb, before.rgb)


@pytest.mark.parametrize("backend", ["numba", "pybullet"])
def test_lidar_ray_passes_where_the_boll_was(farm, backend):
    field = BollField(farm)
    target = field.get(2)
    samples = 720
    cfg = LidarConfig(rings=1, min_elevation_rad=0.0, max_elevation_rad=0.0, samples_per_ring=samples,
                      noise_std_m=0.0, min_range_m=0.0, backend=backend)
    pos, yaw = facing(target.position_m, 1.5)
    pose = np.eye(4)
    pose[:3, :3] = [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
    pose[:3, 3] = pos
    ahead = samples // 2                                     # azimuth 0: along the sensor's x, at the boll
    with SensorScene(farm) as scene:
        lidar = Vlp16Model(scene, cfg)
        rng, sem, pid = lidar.ranges(pose)
        assert sem[ahead] == SemanticClass.BOLL and pid[ahead] == 0
        assert rng[ahead] == pytest.approx(1.5 - target.diameter_m / 2, abs=0.01)
        scan_before = lidar.scan(pose)
        snapshot = scene.visibility
        scene.set_hidden_bolls(hidden_mask(field.count, 2))
        rng2, sem2, pid2 = lidar.ranges(pose)
        assert sem2[ahead] == SemanticClass.PLANT and pid2[ahead] == 0        # the canopy behind it
        assert rng2[ahead] > rng[ahead] + 0.01
        scan_after = lidar.scan(pose)
        assert np.count_nonzero(scan_after.semantic == SemanticClass.BOLL) < np.count_nonzero(
            scan_before.semantic == SemanticClass.BOLL)
        # only the rays that hit that boll changed
        changed = (rng2 != rng) | (sem2 != sem)
        assert changed[ahead] and np.all(sem[changed] == SemanticClass.BOLL)
        # a job that took the earlier snapshot still sees the boll
        rng3, sem3, _ = lidar.ranges(pose, snapshot)
        assert sem3[ahead] == SemanticClass.BOLL and np.array_equal(rng3, rng)


def test_split_keeps_every_triangle_and_gives_each_boll_its_own():
    farm = generate_farm(FarmConfig(rows=1, plants_per_row=3, plant_variants=2, seed=2))
    split = SplitFarm(farm.plants)
    field = BollField(farm)
    assert split.boll_total == field.count and split.plant_count == 3
    for i, plant in enumerate(farm.plants):
        whole = sum(m.triangle_count for m in plant.model.meshes.values())
        first, n = split.boll_first[i], split.boll_count[i]
        parts = [split.instances[i]] + split.instances[3 + first:3 + first + n]
        assert sum(m.triangle_count for p in parts for m in p.model.meshes.values()) == whole
        assert "boll" not in split.instances[i].model.meshes
        for k, inst in enumerate(split.instances[3 + first:3 + first + n]):
            boll = field.get(int(first + k))
            assert inst.plant_id == plant.plant_id == boll.plant_id
            verts = inst.model.meshes["boll"].vertices
            # the boll's own lumps (up to ~1.4 radii out): near its centre (plant-local)
            assert np.all(np.linalg.norm(verts - plant.model.boll_centres[k], axis=1) < 0.8 * boll.diameter_m)
    with SensorScene(farm) as scene:
        with pytest.raises(ValueError, match="one per boll"):
            scene.set_hidden_bolls(np.zeros(field.count + 1, bool))
