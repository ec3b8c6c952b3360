"""Tests of the simulator dataset generator (cottonsim_perception.data.generate).

Small farms (2 rows x 3 plants) and small images keep the whole file within a
few seconds of rendering; every expectation is computed independently of the
generator (hand-made masks, hand-placed bolls, the label reader of yolo_format).
"""
import filecmp
import math
import os

import numpy as np
import pytest

from cottonsim_perception.data import generate as g
from cottonsim_perception.data import yolo_format as yf
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.farm.model import Farm, Plant, PlantModel, Pose2D, SemanticClass, TriangleMesh
from cottonsim_world.sensors.camera import CameraModel
from cottonsim_world.sensors.scene import SceneConfig, SensorScene

TINY_FARM = FarmConfig(rows=2, plants_per_row=3, plant_variants=2)
W, H = 192, 144


def _config(out_dir, **kw):
    base = dict(out_dir=str(out_dir), images_per_task=4, test_images_per_task=2, seeds=(0, 1),
                test_seeds=(7,), val_fraction=0.5, width=W, height=H, base_farm=TINY_FARM,
                images_per_scene=4, ground_margin_m=3.0)
    base.update(kw)
    return g.DatasetConfig(**base)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("ds")
    cfg = _config(out)
    summary = g.generate_dataset(cfg, progress=False)
    return cfg, summary


@pytest.fixture(scope="module")
def base_T_optical():
    return g.camera_transforms(g.DEFAULT_URDF_PATH)


# ------------------------------------------------------------------ the files
def test_layout_counts_and_labels_parse(dataset):
    cfg, summary = dataset
    for task, names in (("seg", yf.SEGMENTATION_CLASS_NAMES), ("det", yf.DETECTION_CLASS_NAMES)):
        root = os.path.join(cfg.out_dir, task)
        dy = yf.read_data_yaml(os.path.join(root, "data.yaml"))
        assert dy.names == names
        assert os.path.samefile(dy.path, root)
        with open(os.path.join(root, "data.yaml")) as fh:
            assert "path:" not in fh.read()            # no absolute root: the folder can be moved
        expected = {"train": 2, "val": 2, "test": 2}      # 4 train/val images over seeds 0 (train), 1 (val)
        assert summary.counts[task] == expected
        for split, n in expected.items():
            pairs = yf.list_pairs(root, split)
            assert len(pairs) == n
            for pair in pairs:
                assert pair.image_path.endswith(".jpg")
                assert os.path.isfile(pair.label_path)
                inst = yf.read_label_file(pair.label_path, task, num_classes=len(names))
                if task == "seg":
                    assert inst and all(i.polygon is not None for i in inst)
                    # ground and sky are in every driving view of the farm
                    assert {i.class_id for i in inst} >= {1}
                else:
                    assert all(i.polygon is None for i in inst)
                    # every det image has its ignore file (possibly empty), also YOLO box lines
                    assert os.path.isfile(yf.ignore_path_for(pair.image_path))
                    yf.read_ignore_boxes(pair.image_path, 640, 480)
    det_instances = sum(summary.instances["det"].values())
    assert det_instances > 0, "side/close views of plants with bolls must label some bolls"


def test_held_out_seeds_never_in_train_or_val(dataset):
    cfg, summary = dataset
    for r in summary.records:
        seed_in_name = int(os.path.basename(r.file)[1:5])
        assert seed_in_name == r.farm_seed
        if r.split == "test":
            assert r.farm_seed in cfg.test_seeds
        else:
            assert r.farm_seed not in cfg.test_seeds
    for task in cfg.tasks:
        for split in ("train", "val"):
            for pair in yf.list_pairs(os.path.join(cfg.out_dir, task), split):
                assert int(os.path.basename(pair.image_path)[1:5]) not in cfg.test_seeds
    # train and val farms are disjoint too
    train = {r.farm_seed for r in summary.records if r.split == "train"}
    val = {r.farm_seed for r in summary.records if r.split == "val"}
    assert train and val and not (train & val)


def test_plan_keeps_test_seeds_apart_and_spreads_images():
    cfg = g.DatasetConfig(out_dir="/tmp/unused", images_per_task=103, seeds=tuple(range(10)),
                          test_seeds=(50, 51, 52), val_fraction=0.2, test_images_per_task=10)
    jobs = g.plan_jobs(cfg)
    splits = g.split_seeds(cfg)
    assert splits["val"] == (8, 9) and splits["train"] == tuple(range(8))
    for job in jobs:
        assert (job.split == "test") == (job.farm_seed in (50, 51, 52))
        assert (job.split == "val") == (job.farm_seed in (8, 9))
    for task in ("seg", "det"):
        per_split = {s: sum(dict(j.counts)[task] for j in jobs if j.split == s) for s in g.SPLITS}
        assert per_split == {"train": 83, "val": 20, "test": 10}   # 103 = 10 x 10 + 3 extra to seeds 0-2


def test_same_seed_gives_identical_output(tmp_path):
    kw = dict(images_per_task=2, test_images_per_task=0, seeds=(3,), test_seeds=(), val_fraction=0.0)
    a = g.generate_dataset(_config(tmp_path / "a", **kw), progress=False)
    b = g.generate_dataset(_config(tmp_path / "b", **kw), progress=False)
    assert a.images == b.images == 4
    for task in ("seg", "det"):
        for sub in ("images", "labels", "ignore") if task == "det" else ("images", "labels"):
            da, db = tmp_path / "a" / task / sub / "train", tmp_path / "b" / task / sub / "train"
            names = sorted(os.listdir(da))
            assert names == sorted(os.listdir(db)) and len(names) == 2
            match, mismatch, errors = filecmp.cmpfiles(da, db, names, shallow=False)
            assert not mismatch and not errors
    # a different dataset seed changes the poses and so the images
    c = g.generate_dataset(_config(tmp_path / "c", dataset_seed=1, tasks=("seg",), **kw), progress=False)
    assert c.images == 2
    assert not filecmp.cmp(tmp_path / "a" / "seg" / "images" / "train" / "s0003_00000.jpg",
                           tmp_path / "c" / "seg" / "images" / "train" / "s0003_00000.jpg", shallow=False)


# ------------------------------------------------------------------- labels
def _render_views(task, n, base_T_optical, seed=5):
    farm = generate_farm(g.sample_farm_config(TINY_FARM, seed, g.VariationConfig()))
    cfg = _config("/tmp/unused")
    frames = []
    with SensorScene(farm, SceneConfig(collision_source="primitives", ground_margin_m=3.0)) as scene:
        cam = CameraModel(scene, cfg.camera_config())
        rng = np.random.default_rng(seed)
        for _ in range(n):
            shot = g.sample_robot_pose(farm, task, rng, g.VariationConfig(), base_T_optical)
            pose = shot.world_T_base @ base_T_optical[shot.camera]
            frames.append((cam.render(pose), pose, shot))
        K = cam.intrinsics().K
    return farm, frames, K


def test_seg_polygons_round_trip_to_the_semantic_mask(base_T_optical):
    _, frames, _ = _render_views("seg", 4, base_T_optical)
    for frame, _, _ in frames:
        inst = g.segmentation_instances(frame.semantic)
        classes = [i.class_id for i in inst]
        assert len(set(classes)) == len(classes), "default labels: one line per class"
        regions = g.segmentation_instances(frame.semantic, g.LabelConfig(seg_instances="region"))
        assert len(regions) >= len(inst)
        # through the text format and the project's reader, then rasterised independently
        lines = [yf.format_label_line(i, "seg") for i in inst]
        parsed = [yf.parse_label_line(line, "seg", 3) for line in lines]
        sem = frame.semantic
        truth = {0: (sem == SemanticClass.PLANT) | (sem == SemanticClass.BOLL),
                 1: sem == SemanticClass.GROUND, 2: sem == SemanticClass.SKY}
        for cls, mask in truth.items():
            drawn = np.zeros_like(mask)
            for p in parsed:
                if p.class_id == cls:
                    drawn |= yf.polygon_to_mask(p.polygon_px(W, H), H, W)
            union = np.count_nonzero(mask | drawn)
            if union == 0:
                continue
            iou = np.count_nonzero(mask & drawn) / union
            assert iou >= 0.98, f"class {cls}: IoU {iou:.4f}"


def test_mask_with_hole_and_island_is_reproduced_exactly():
    mask = np.zeros((40, 50), dtype=bool)
    mask[5:35, 5:45] = True          # a frame ...
    mask[12:28, 12:38] = False       # ... with a hole ...
    mask[17:23, 20:30] = True        # ... holding an island
    mask[2, 48] = True               # a single-pixel speck: below min_area, dropped
    polys = g.mask_to_label_polygons(mask, epsilon_px=0.0, min_area_px=4.0)
    assert len(polys) == 2
    drawn = np.zeros_like(mask)
    for p in polys:
        drawn |= yf.polygon_to_mask(p, 40, 50)
    expected = mask.copy()
    expected[2, 48] = False
    assert np.array_equal(drawn, expected)


def test_every_labelled_box_holds_visible_boll_pixels(base_T_optical):
    farm, frames, K = _render_views("det", 4, base_T_optical, seed=6)
    total = 0
    for frame, pose, shot in frames:
        assert shot.camera in g.CAMERAS
        bolls = [b for b in g.boll_boxes(frame.semantic, frame.depth_m, frame.plant_id, farm, pose, K)
                 if not b.ignore]
        for b in bolls:
            assert b.depth_m <= g.LabelConfig().max_boll_depth_m
            x1, y1, x2, y2 = (int(v) for v in b.box_xyxy_px)
            assert 0 <= x1 < x2 <= W and 0 <= y1 < y2 <= H
            assert x2 - x1 >= 4 and y2 - y1 >= 4
            win = frame.semantic[y1:y2, x1:x2] == SemanticClass.BOLL
            # the box is tight: boll pixels on all four edges
            assert win[0].any() and win[-1].any() and win[:, 0].any() and win[:, -1].any()
            assert np.count_nonzero(win) >= b.visible_px
            # and on the boll's own plant, at about the boll's depth
            ids = frame.plant_id[y1:y2, x1:x2][win]
            assert b.plant_id in set(ids.tolist())
        total += len(bolls)
    assert total > 0


# --- a hand-made scene: one boll behind a leaf, one in the open
def _sphere(centre, r, n=10):
    verts, faces = [], []
    for i in range(n + 1):
        th = math.pi * i / n
        for j in range(n):
            ph = 2 * math.pi * j / n
            verts.append([r * math.sin(th) * math.cos(ph), r * math.sin(th) * math.sin(ph), r * math.cos(th)])
    for i in range(n):
        for j in range(n):
            a, b = i * n + j, i * n + (j + 1) % n
            faces += [[a, a + n, b + n], [a, b + n, b]]
    faces = np.array(faces)
    return np.asarray(verts) + centre, np.concatenate([faces, faces[:, ::-1]])   # both windings


def _plant_with_bolls(leaf: bool) -> PlantModel:
    hidden, open_ = np.array([0.0, 0.0, 0.5]), np.array([0.0, 0.35, 0.5])
    bv, bf = [], []
    for c in (hidden, open_):
        v, f = _sphere(c, 0.03)
        bf.append(f + sum(len(x) for x in bv))
        bv.append(v)
    meshes = {"boll": TriangleMesh(np.concatenate(bv).astype(np.float32), np.concatenate(bf).astype(np.int32),
                                   (0.95, 0.95, 0.95, 1.0), SemanticClass.BOLL)}
    if leaf:   # a 0.2 x 0.2 m leaf 0.15 m in front of the hidden boll (camera on -x), two-sided
        lv = np.array([[-0.15, -0.1, 0.4], [-0.15, 0.1, 0.4], [-0.15, 0.1, 0.6], [-0.15, -0.1, 0.6]], np.float32)
        lf = np.array([[0, 1, 2], [0, 2, 3], [2, 1, 0], [3, 2, 0]], np.int32)
        meshes["leaf"] = TriangleMesh(lv, lf, (0.2, 0.5, 0.15, 1.0), SemanticClass.PLANT)
    return PlantModel(meshes=meshes, collision=[], boll_centres=np.array([hidden, open_]),
                      boll_radii=np.array([0.03, 0.03]), height_m=0.6, width_m=0.3)


@pytest.mark.parametrize("leaf", [True, False])
def test_boll_hidden_behind_a_leaf_is_not_labelled(leaf):
    farm = Farm(config=None, plants=[Plant(0, 0, 0, 0.0, 0.0, 0.0, _plant_with_bolls(leaf))], lanes=[],
                spawn=Pose2D(0.0, 0.0, 0.0))
    # optical frame at (-1, 0.15, 0.5) looking along world +x (z fwd, x right = -y world, y down = -z)
    pose = np.eye(4)
    pose[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    pose[:3, 3] = (-1.0, 0.15, 0.5)
    cfg = _config("/tmp/unused")
    with SensorScene(farm, SceneConfig(ground_margin_m=3.0)) as scene:
        cam = CameraModel(scene, cfg.camera_config())
        frame = cam.render(pose)
        K = cam.intrinsics().K
    bolls = g.boll_boxes(frame.semantic, frame.depth_m, frame.plant_id, farm, pose, K)
    assert sorted(b.boll_index for b in bolls) == ([1] if leaf else [0, 1])
    assert not any(b.ignore for b in bolls)
    # beyond the working range (1 m away here) the same bolls become ignore boxes
    far = g.boll_boxes(frame.semantic, frame.depth_m, frame.plant_id, farm, pose, K,
                       g.LabelConfig(max_boll_depth_m=0.9))
    assert [b.box_xyxy_px for b in far] == [b.box_xyxy_px for b in bolls]
    assert all(b.ignore for b in far)
    lines = g.detection_instances(far, frame.semantic.shape[1], frame.semantic.shape[0])
    ignore_lines = g.detection_instances(far, frame.semantic.shape[1], frame.semantic.shape[0], ignored=True)
    assert lines == [] and len(ignore_lines) == len(bolls)
    # the open boll's box surrounds its projection: centre column of a point at y = 0.35 m, 1 m away
    fx, cx = K[0, 0], K[0, 2]
    u_open = fx * (-(0.35 - 0.15)) / 1.0 + cx
    box = [b for b in bolls if b.boll_index == 1][0].box_xyxy_px
    assert box[0] - 1 <= u_open <= box[2] + 1
    r_px = fx * 0.03 / 1.0
    assert abs((box[2] - box[0]) - 2 * r_px) <= 3.0


# ------------------------------------------------------------ poses / looks
def test_poses_look_where_they_should(base_T_optical):
    farm = generate_farm(FarmConfig(rows=3, plants_per_row=5, plant_variants=1))
    rng = np.random.default_rng(0)
    v = g.VariationConfig(headland_probability=0.0, front_close_probability=0.0)
    for _ in range(20):
        shot = g.sample_robot_pose(farm, "seg", rng, v, base_T_optical)
        axis = (shot.world_T_base @ base_T_optical[shot.camera])[:3, 2]
        assert shot.mode == "lane" and shot.camera == g.CAMERA_FRONT
        assert abs(axis[0]) < math.sin(math.radians(20))           # along the rows (world y)
        lane_x = min(abs(shot.world_T_base[0, 3] - l.x_m) for l in farm.lanes)
        assert lane_x <= 2.5 * v.lane_offset_std_m + 1e-9
        assert abs(shot.world_T_base[2, 3] - 0.13228) <= 0.0251
    for _ in range(20):
        shot = g.sample_robot_pose(farm, "det", rng, v, base_T_optical)
        cam = shot.world_T_base @ base_T_optical[shot.camera]
        assert shot.mode == "side" and shot.camera in (g.CAMERA_LEFT, g.CAMERA_RIGHT)
        # the side camera looks across the rows, towards the nearest row
        rows_x = np.array([farm.config.row_x_m(r) for r in range(3)])
        nearest = rows_x[np.argmin(abs(rows_x - cam[0, 3]))]
        assert np.sign(cam[0, 2]) == np.sign(nearest - cam[0, 3])
        assert abs(cam[0, 2]) > 0.8


def test_photometric_identity_and_exposure():
    rgb = np.random.default_rng(0).integers(0, 256, (8, 9, 3), dtype=np.uint8)
    ident = g.VariationConfig(exposure_range=(1.0, 1.0), contrast_range=(1.0, 1.0), gamma_range=(1.0, 1.0),
                              white_balance_max=0.0, noise_std_range=(0.0, 0.0))
    out = g.apply_photometric(rgb, np.random.default_rng(1), ident)
    assert np.abs(out.astype(int) - rgb.astype(int)).max() <= 1
    bright = g.apply_photometric(rgb, np.random.default_rng(1), g.VariationConfig(
        exposure_range=(1.2, 1.2), contrast_range=(1.0, 1.0), gamma_range=(1.0, 1.0),
        white_balance_max=0.0, noise_std_range=(0.0, 0.0)))
    expected = np.clip(np.floor(rgb * 1.2 + 0.5), 0, 255)
    assert np.abs(bright.astype(int) - expected).max() <= 1
    with pytest.raises(ValueError, match="uint8"):
        g.apply_photometric(rgb.astype(np.float32), np.random.default_rng(0), ident)


def test_farm_variation_stays_valid_and_varies():
    cfgs = [g.sample_farm_config(FarmConfig(), s, g.VariationConfig()) for s in range(30)]
    assert {c.growth_stage for c in cfgs} == {"cutout", "defoliated"}
    assert len({c.plant_height_m for c in cfgs}) == 30
    assert all(c.seed == s for s, c in enumerate(cfgs))
    assert all(c.free_lane_width_m >= c.robot_width_m + c.lane_clearance_margin_m for c in cfgs)
    assert cfgs[3] == g.sample_farm_config(FarmConfig(), 3, g.VariationConfig())


# --------------------------------------------------------------- bad input
@pytest.mark.parametrize("kw, word", [
    (dict(test_seeds=(1, 9)), "test_seeds"),
    (dict(val_fraction=1.5), "val_fraction"),
    (dict(seeds=(0,), val_fraction=0.1), "val_fraction"),
    (dict(tasks=("seg", "cls")), "tasks"),
    (dict(images_per_task=-1), "images_per_task"),
    (dict(workers=0), "workers"),
    (dict(image_format="gif"), "image_format"),
    (dict(jpeg_quality=101), "jpeg_quality"),
    (dict(urdf_path="/nonexistent.urdf"), "urdf_path"),
    (dict(test_seeds=(), test_images_per_task=5), "test_seeds"),
])
def test_bad_dataset_config_names_the_parameter(tmp_path, kw, word):
    with pytest.raises(ValueError, match=word):
        _config(tmp_path, **kw)


def test_bad_variation_and_label_config():
    with pytest.raises(ValueError, match="exposure_range"):
        g.VariationConfig(exposure_range=(1.3, 0.7))
    with pytest.raises(ValueError, match="defoliated_probability"):
        g.VariationConfig(defoliated_probability=2.0)
    with pytest.raises(ValueError, match="seg_instances"):
        g.LabelConfig(seg_instances="pixel")
    with pytest.raises(ValueError, match="polygon_epsilon_px"):
        g.LabelConfig(polygon_epsilon_px=-1.0)
    with pytest.raises(ValueError, match="renderer"):
        _config("/tmp/unused", renderer="no-such-renderer").camera_config()


def test_cli_parsers():
    assert g.parse_seed_list("0-3,7, 9") == (0, 1, 2, 3, 7, 9)
    assert g.parse_seed_list("") == ()
    assert g.parse_image_size("640x480") == (640, 480)
    for bad in ("3-1", "a", "1-b"):
        with pytest.raises(ValueError, match="seed"):
            g.parse_seed_list(bad)
    for bad in ("640", "640x", "0x10", "10x10x3"):
        with pytest.raises(ValueError, match="WxH|between"):
            g.parse_image_size(bad)


@pytest.mark.parametrize("task, option, column, values_at_1_and_0, bad_value, field", [
    ("seg", "--defoliated-probability", "growth_stage", ("defoliated", "cutout"), "1.5", "defoliated_probability"),
    ("det", "--close-probability", "mode", ("close", "side"), "-0.1", "front_close_probability"),
])
def test_cli_probability_options_set_every_images_manifest_value(tmp_path, capsys, perception_script, task,
                                                                 option, column, values_at_1_and_0, bad_value,
                                                                 field):
    import csv

    script = perception_script("generate_dataset")
    farm_yaml = tmp_path / "farm.yaml"
    farm_yaml.write_text("rows: 2\nplants_per_row: 3\nplant_variants: 2\n")
    seen = {}
    for p in ("1", "0"):
        out = tmp_path / f"p{p}"
        code = script.main(["--task", task, "--out", str(out), "--images", "3", "--seeds", "0,1",
                            "--val-fraction", "0", "--imgsz", "96x72", "--farm-config", str(farm_yaml),
                            option, p, "--quiet"])
        assert code == 0
        with open(out / task / "manifest.csv") as fh:
            seen[p] = {row[column] for row in csv.DictReader(fh)}
    assert seen == {"1": {values_at_1_and_0[0]}, "0": {values_at_1_and_0[1]}}
    assert script.main(["--out", str(tmp_path / "bad"), option, bad_value]) == 2
    assert field in capsys.readouterr().err
