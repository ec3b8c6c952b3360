"""Procedural cotton plant: materials, size envelope, budgets, determinism."""
import numpy as np
import pytest

from cottonsim_world.farm.model import SemanticClass
from cottonsim_world.farm.plant_model import CottonPlantConfig, build_cotton_plant


def _tris(model):
    return sum(m.triangle_count for m in model.meshes.values())


@pytest.fixture(scope="module")
def plant():
    return build_cotton_plant(CottonPlantConfig(boll_count=12), 3)


def test_materials_and_semantics(plant):
    assert set(plant.meshes) == {"stem", "leaf", "dead_leaf", "boll"}
    for name, mesh in plant.meshes.items():
        assert mesh.semantic == (SemanticClass.BOLL if name == "boll" else SemanticClass.PLANT)
        assert mesh.vertices.dtype == np.float32 and mesh.vertices.shape[1] == 3
        assert mesh.faces.dtype == np.int32 and mesh.faces.shape[1] == 3
        assert mesh.faces.min() >= 0 and mesh.faces.max() < len(mesh.vertices)
        assert len(mesh.rgba) == 4 and all(0.0 <= c <= 1.0 for c in mesh.rgba)
    # colours: leaves green, bolls white, dead leaves brownish (red > blue)
    r, g, b, _ = plant.meshes["leaf"].rgba
    assert g > r and g > b
    assert min(plant.meshes["boll"].rgba[:3]) > 0.85
    r, g, b, _ = plant.meshes["dead_leaf"].rgba
    assert r > g > b


@pytest.mark.parametrize("detail", ["high", "low"])
def test_bolls_face_outwards(detail):
    # a back-face culling renderer must see a boll's near side: every face counter-clockwise from outside
    model = build_cotton_plant(CottonPlantConfig(boll_count=10, detail=detail), 4)
    mesh = model.meshes["boll"]
    v, f = mesh.vertices.astype(float), mesh.faces
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    mid = v[f].mean(axis=1)
    nearest = np.argmin(np.linalg.norm(mid[:, None] - model.boll_centres[None], axis=2), axis=1)
    assert len(f) >= 10 * 8
    assert np.all(np.einsum("ij,ij->i", normal, mid - model.boll_centres[nearest]) > 0.0)


@pytest.mark.parametrize("stage", ["cutout", "defoliated"])
@pytest.mark.parametrize("detail", ["high", "low"])
def test_geometry_inside_the_nominal_envelope(stage, detail):
    cfg = CottonPlantConfig(height_m=1.1, width_m=0.6, boll_count=16, growth_stage=stage, detail=detail)
    m = build_cotton_plant(cfg, 11)
    v = np.concatenate([mesh.vertices for mesh in m.meshes.values()]).astype(float)
    assert np.all(np.hypot(v[:, 0], v[:, 1]) <= 0.3 + 1e-6)
    assert v[:, 2].min() >= 0.0 and v[:, 2].max() <= 1.1 + 1e-6
    assert v[:, 2].max() > 0.85 * 1.1                     # it really is about that tall
    assert np.hypot(v[:, 0], v[:, 1]).max() > 0.2        # and bushy
    # bolls: count, radius 2-3.5 cm (4-7 cm wide), inside the canopy
    assert m.boll_centres.shape == (16, 3) and m.boll_radii.shape == (16,)
    assert np.all((m.boll_radii >= 0.02) & (m.boll_radii <= 0.035))
    assert np.all(np.hypot(m.boll_centres[:, 0], m.boll_centres[:, 1]) <= 0.3)
    assert np.all((m.boll_centres[:, 2] > 0.1) & (m.boll_centres[:, 2] < 1.1))
    # each boll centre is surrounded by boll vertices
    bv = m.meshes["boll"].vertices.astype(float)
    d = np.linalg.norm(bv[:, None, :] - m.boll_centres[None], axis=2).min(axis=0)
    assert np.all(d < 2 * m.boll_radii)
    assert ("leaf" in m.meshes) == (stage == "cutout")


def test_triangle_budgets():
    for seed in range(3):
        high = build_cotton_plant(CottonPlantConfig(boll_count=16, detail="high"), seed)
        low = build_cotton_plant(CottonPlantConfig(boll_count=16, detail="low"), seed)
        assert 1500 <= _tris(high) <= 4000
        assert 100 <= _tris(low) <= 600
        assert len(high.meshes["leaf"].faces) // 24 >= 40       # many leaves (24 faces each)


def test_collision_primitives_cover_the_canopy(plant):
    names = [p.name for p in plant.collision]
    assert names[0] == "stem" and {"canopy_low", "canopy_mid", "canopy_top"} <= set(names)
    for p in plant.collision:
        assert p.shape == "cylinder"
        radius, length = p.size
        assert 0 < radius <= 0.35 and length > 0
        assert p.position[2] - length / 2 >= -1e-9 and p.position[2] + length / 2 <= 1.0 + 1e-6
    mid = next(p for p in plant.collision if p.name == "canopy_mid")
    top = next(p for p in plant.collision if p.name == "canopy_top")
    assert mid.size[0] > 0.15 and top.size[0] <= mid.size[0] + 0.05   # widest in the middle
    # most leaf vertices lie inside some canopy cylinder
    v = plant.meshes["leaf"].vertices.astype(float)
    inside = np.zeros(len(v), bool)
    for p in plant.collision[1:]:
        r, L = p.size
        inside |= (np.hypot(v[:, 0], v[:, 1]) <= r) & (np.abs(v[:, 2] - p.position[2]) <= L / 2)
    assert inside.mean() > 0.75


def test_deterministic_per_seed_and_varies_between_seeds():
    a = build_cotton_plant(CottonPlantConfig(), 5)
    b = build_cotton_plant(CottonPlantConfig(), np.random.default_rng(5))
    c = build_cotton_plant(CottonPlantConfig(), 6)
    for name in a.meshes:
        np.testing.assert_array_equal(a.meshes[name].vertices, b.meshes[name].vertices)
        np.testing.assert_array_equal(a.meshes[name].faces, b.meshes[name].faces)
    np.testing.assert_array_equal(a.boll_centres, b.boll_centres)
    assert not np.array_equal(a.meshes["leaf"].vertices[:50], c.meshes["leaf"].vertices[:50])


def test_zero_bolls_and_bad_config():
    m = build_cotton_plant(CottonPlantConfig(boll_count=0), 1)
    assert "boll" not in m.meshes and m.boll_centres.shape == (0, 3)
    with pytest.raises(ValueError, match="height_m"):
        CottonPlantConfig(height_m=0)
    with pytest.raises(ValueError, match="detail"):
        CottonPlantConfig(detail="medium")
    with pytest.raises(ValueError, match="boll_count"):
        CottonPlantConfig(boll_count=-1)
    with pytest.raises(ValueError, match="rng"):
        build_cotton_plant(CottonPlantConfig(), rng="abc")
