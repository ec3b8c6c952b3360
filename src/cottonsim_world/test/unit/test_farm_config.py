"""FarmConfig: defaults, validation messages, dict round trip."""
import math

import pytest

from cottonsim_world.farm.config import FarmConfig


def test_defaults_are_the_papers_farm():
    c = FarmConfig()
    assert (c.rows, c.plants_per_row) == (9, 20)
    assert (c.row_spacing_m, c.plant_spacing_m, c.plant_height_m, c.plant_width_m) == (1.8, 0.7, 1.0, 0.7)
    assert c.lane_count == 10
    # stems span ~8.95 .. 22.25 m
    assert c.first_plant_y_m == pytest.approx(8.95)
    assert c.last_plant_y_m == pytest.approx(8.95 + 19 * 0.7)
    assert (c.spawn_x_m, c.spawn_y_m, c.spawn_yaw_rad) == (-6.0, 1.0, pytest.approx(math.pi / 2))
    assert c.free_lane_width_m == pytest.approx(1.1)


@pytest.mark.parametrize("kwargs, name", [
    (dict(rows=0), "rows"),
    (dict(plants_per_row=0), "plants_per_row"),
    (dict(row_spacing_m=0.0), "row_spacing_m"),
    (dict(plant_spacing_m=-0.7), "plant_spacing_m"),
    (dict(plant_height_m=0.0), "plant_height_m"),
    (dict(position_jitter_m=0.5), "position_jitter_m"),
    (dict(position_jitter_m=-0.1), "position_jitter_m"),
    (dict(height_jitter_fraction=0.9), "height_jitter_fraction"),
    (dict(missing_plant_fraction=1.0), "missing_plant_fraction"),
    (dict(bolls_per_plant=(10, 5)), "bolls_per_plant"),
    (dict(bolls_per_plant=(1, 2, 3)), "bolls_per_plant"),
    (dict(growth_stage="flowering"), "growth_stage"),
    (dict(plant_detail="ultra"), "plant_detail"),
    (dict(seed=-3), "seed"),
    (dict(rows=2.5), "rows"),
    (dict(row_spacing_m=float("nan")), "row_spacing_m"),
    (dict(row_spacing_m="wide"), "row_spacing_m"),
    # free lane 1.4 - 0.7 = 0.7 < 0.67 + 0.1
    (dict(row_spacing_m=1.4), "row_spacing_m"),
    (dict(route_entry_distance_m=0.0), "route_entry_distance_m"),
])
def test_bad_values_raise_naming_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        FarmConfig(**kwargs)


def test_lane_clearance_accounts_for_jitter_and_robot():
    # 1.6 - 0.7 = 0.9 free; robot 0.67 + margin 0.1 = 0.77 fits ...
    FarmConfig(row_spacing_m=1.6)
    # ... but not with 0.1 m jitter on both canopies (0.9 - 0.2 = 0.7)
    with pytest.raises(ValueError, match="row_spacing_m"):
        FarmConfig(row_spacing_m=1.6, position_jitter_m=0.1)
    with pytest.raises(ValueError, match="robot_width_m"):
        FarmConfig(robot_width_m=1.2)


def test_narrow_lanes_allowed_only_when_lane_fit_is_not_required():
    narrow = FarmConfig(row_spacing_m=1.0, require_lane_fit=False)
    assert narrow.free_lane_width_m == pytest.approx(0.3)
    with pytest.raises(ValueError, match="require_lane_fit"):
        FarmConfig(require_lane_fit="no")
    assert FarmConfig.from_dict({"row_spacing_m": 1.2, "require_lane_fit": False}).row_spacing_m == 1.2


def test_layout_helpers():
    c = FarmConfig(first_lane_x_m=2.0, row_spacing_m=2.0)
    assert c.lane_x_m(0) == 2.0 and c.lane_x_m(3) == pytest.approx(-4.0)
    assert c.row_x_m(0) == pytest.approx(1.0)
    assert c.row_x_m(1) == pytest.approx(-1.0)


def test_dict_round_trip_and_yaml_shapes():
    c = FarmConfig(seed=7, bolls_per_plant=[3, 9], growth_stage="defoliated", rows=3.0)
    assert c.bolls_per_plant == (3, 9) and c.rows == 3 and isinstance(c.rows, int)
    d = c.to_dict()
    assert d["bolls_per_plant"] == [3, 9]
    assert FarmConfig.from_dict(d) == c
    assert FarmConfig.from_dict({"farm": {"seed": 7}}).seed == 7
    assert FarmConfig.from_dict(None) == FarmConfig()
    with pytest.raises(ValueError, match="unknown farm config key"):
        FarmConfig.from_dict({"rowz": 3})
    with pytest.raises(ValueError, match="mapping"):
        FarmConfig.from_dict([1, 2])


def test_yaml_file_documents_every_key():
    import os

    import yaml
    here = os.path.dirname(__file__)
    path = os.path.join(here, "..", "..", "config", "farm.yaml")
    with open(path) as fh:
        data = yaml.safe_load(fh)
    assert set(data["farm"]) == set(FarmConfig().to_dict())
    assert FarmConfig.from_dict(data) == FarmConfig()
