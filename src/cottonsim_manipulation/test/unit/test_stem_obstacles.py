"""Estimated stems as obstacles of the approach plan (planning/stems.py with plan_approach)."""
import numpy as np
import pytest
from hand_built_scene import GROUND_Z_M, STOW_RAD

from cottonsim_manipulation.planning.approach import ApproachConfig, plan_approach
from cottonsim_manipulation.planning.stems import merge_stems, stem_obstacles


def test_estimates_of_one_plant_merge_into_one_stem():
    # three bolls of a plant estimate its stem within 3 cm; the next plant 0.7 m along the row
    estimates = [(0.9, 0.01), (0.9, -0.02), (0.9, 0.7), (0.9, 0.0), (-0.9, 0.0)]
    np.testing.assert_allclose(merge_stems(estimates, 0.1), [(0.9, -1 / 300), (0.9, 0.7), (-0.9, 0.0)], atol=1e-12)
    assert len(merge_stems(estimates, 0.005)) == 5
    assert merge_stems([], 0.1).shape == (0, 2)


def test_stem_obstacles_are_vertical_capsules_from_the_ground_up():
    cfg = ApproachConfig(stem_radius_m=0.025, stem_height_m=1.1)
    stems = stem_obstacles([(0.9, 0.0), (0.92, 0.0), (0.9, 0.7)], GROUND_Z_M, cfg)
    assert len(stems) == 2 and stems.names == ("stem_0", "stem_1")
    np.testing.assert_allclose(stems.start_m, [(0.91, 0.0, GROUND_Z_M), (0.9, 0.7, GROUND_Z_M)])
    np.testing.assert_allclose(stems.end_m - stems.start_m, [(0, 0, 1.1)] * 2)
    np.testing.assert_allclose(stems.radius_m, [0.025, 0.025])
    assert len(stem_obstacles(np.zeros((0, 2)), 0.0)) == 0
    # moved into another frame with the CapsuleSet's transform
    shift = np.eye(4)
    shift[:3, 3] = (0.0, 0.0, 0.5)
    np.testing.assert_allclose(stems.transformed(shift).start_m[:, 2], GROUND_Z_M + 0.5)


def test_bad_stems_and_config_are_refused():
    with pytest.raises(ValueError, match="stem positions"):
        stem_obstacles([(0.9, np.nan)], 0.0)
    with pytest.raises(ValueError, match="stem positions"):
        stem_obstacles([(0.9, 0.0, 0.0)], 0.0)
    with pytest.raises(ValueError, match="ground_z_m"):
        stem_obstacles([(0.9, 0.0)], float("inf"))
    for name, value in (("stem_radius_m", -0.01), ("stem_radius_m", 0.5), ("stem_height_m", float("nan")),
                        ("stem_merge_distance_m", "0.1")):
        with pytest.raises(ValueError, match=name):
            ApproachConfig(**{name: value})


def along_the_row_case():
    """A boll facing along the row (arm +y) with the next plant's estimated stem 12 cm ahead of it."""
    boll = np.array([0.75, 0.05, GROUND_Z_M + 0.5])
    return boll, np.array([0.0, 1.0, 0.0]), stem_obstacles([(0.75, 0.17)], GROUND_Z_M)


def test_an_approach_through_an_estimated_stem_is_rerouted(model):
    boll, outward, stems = along_the_row_case()
    blind = plan_approach(boll, outward, STOW_RAD, model)
    assert blind.ok and blind.plan.yaw_rad == 0.0
    # without the stems the plan drives the nozzle through the estimated stem
    assert any(model.first_collision(t, stems) is not None for t in (blind.plan.approach, blind.plan.retreat))
    aware = plan_approach(boll, outward, STOW_RAD, model, stems)
    assert aware.ok and aware.plan.yaw_rad != 0.0
    for trajectory in (aware.plan.transit, aware.plan.approach, aware.plan.retreat):
        assert model.first_collision(trajectory, stems, step_rad=0.005) is None


def test_an_approach_with_no_way_past_an_estimated_stem_is_rejected(model):
    boll, outward, stems = along_the_row_case()
    result = plan_approach(boll, outward, STOW_RAD, model, stems, ApproachConfig(yaw_samples_rad=(0.0,)))
    assert result.reason == "collision" and result.plan is None
    assert "stem_0" in result.detail
