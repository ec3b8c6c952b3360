"""The boll field core: ids, positions and sizes from the farm, state transitions, queries, determinism."""
import numpy as np
import pytest

from cottonsim_world.farm.bolls import BollField, BollFieldConfig, BollState
from cottonsim_world.farm.config import FarmConfig
from cottonsim_world.farm.generator import generate_farm

SMALL_FARM = FarmConfig(rows=2, plants_per_row=3, plant_detail="low", missing_plant_fraction=0.2, seed=5)


@pytest.fixture(scope="module")
def farm():
    return generate_farm(SMALL_FARM)


def test_ids_follow_the_plants_and_their_models(farm):
    field = BollField(farm)
    expected = [(p.plant_id, k, c, 2.0 * r) for p in farm.plants
                for k, (c, r) in enumerate(zip(p.boll_centres_world(), p.model.boll_radii))]
    assert field.count == len(expected) > 0
    for boll_id, (plant_id, k, centre, diameter) in enumerate(expected):
        b = field.get(boll_id)
        assert (b.boll_id, b.plant_id, b.index_on_plant) == (boll_id, plant_id, k)
        assert np.allclose(b.position_m, centre) and b.diameter_m == pytest.approx(diameter)
        assert b.state == BollState.ON_PLANT and b.holder == ""
        plant = next(p for p in farm.plants if p.plant_id == plant_id)
        away = np.array([centre[0] - plant.x_m, centre[1] - plant.y_m, 0.0])
        assert np.allclose(field.outward[boll_id], away / np.linalg.norm(away))
    assert not field.off_plant_mask().any()


def harvest_some(field):
    """The same sequence of arm actions."""
    field.detach(3, "nozzle", (1.0, 2.0, 0.8))
    field.move_held("nozzle", (1.1, 2.0, 0.9))
    field.drop_in_bin(3, (1.2, 2.0, 0.5))
    field.drop_in_bin(1)
    field.detach(0, "nozzle")


def test_same_seed_and_actions_give_the_same_field():
    a, b = BollField(generate_farm(SMALL_FARM)), BollField(generate_farm(SMALL_FARM))
    other = BollField(generate_farm(FarmConfig(**{**SMALL_FARM.to_dict(), "seed": 6})))
    assert np.array_equal(a.positions_m(), b.positions_m())
    assert a.count != other.count or not np.array_equal(a.positions_m(), other.positions_m())
    harvest_some(a)
    harvest_some(b)
    assert np.array_equal(a.positions_m(), b.positions_m()) and np.array_equal(a.states(), b.states())
    assert a.revision == b.revision == 5
    assert a.all() == b.all()


def test_transitions_and_what_each_leaves_behind(farm):
    field = BollField(farm)
    start = field.positions_m()
    held = field.detach(2, "nozzle")
    assert held.state == BollState.HELD and held.holder == "nozzle" and np.allclose(held.position_m, start[2])
    assert field.held_by("nozzle") == [2]
    assert field.move_held("nozzle", (0.5, 0.5, 1.0)) == [2]
    assert field.get(2).position_m == (0.5, 0.5, 1.0)
    binned = field.drop_in_bin(2)
    assert binned.state == BollState.IN_BIN and binned.holder == "" and binned.position_m == (0.5, 0.5, 1.0)
    assert field.held_by("nozzle") == []
    assert np.array_equal(field.off_plant_mask(), np.arange(field.count) == 2)
    # the others did not move
    others = np.arange(field.count) != 2
    assert np.array_equal(field.positions_m()[others], start[others])
    # straight to the bin (a vacuum tube)
    assert field.drop_in_bin(4).state == BollState.IN_BIN


def test_refused_transitions_name_the_boll_and_the_reason(farm):
    field = BollField(farm)
    field.detach(0, "nozzle")
    with pytest.raises(ValueError, match="boll 0 cannot be detached: it is HELD"):
        field.detach(0, "other")
    with pytest.raises(ValueError, match="already holds 1 boll"):
        field.detach(1, "nozzle")
    field.drop_in_bin(0)
    with pytest.raises(ValueError, match="boll 0 is already IN_BIN"):
        field.drop_in_bin(0)
    with pytest.raises(ValueError, match="cannot go back on its plant"):
        field.set_state(0, BollState.ON_PLANT)
    with pytest.raises(ValueError, match="unknown boll id 9999"):
        field.get(9999)
    with pytest.raises(ValueError, match="unknown boll id -1"):
        field.detach(-1, "nozzle")
    with pytest.raises(ValueError, match="holder must be a non-empty name"):
        field.detach(1, " ")
    with pytest.raises(ValueError, match="position_m must be 3 finite"):
        field.detach(1, "nozzle", (0.0, float("nan"), 0.0))
    with pytest.raises(ValueError, match="unknown boll state 7"):
        field.set_state(1, 7)
    with pytest.raises(ValueError, match="max_held_per_holder"):
        BollFieldConfig(max_held_per_holder=0)
    revision = field.revision
    with pytest.raises(ValueError):
        field.detach(0, "nozzle")
    assert field.revision == revision            # a refused change changes nothing


def test_set_state_is_the_service_view_of_the_transitions(farm):
    field = BollField(farm, BollFieldConfig(max_held_per_holder=2))
    assert field.set_state(5, BollState.ON_PLANT).state == BollState.ON_PLANT and field.revision == 0
    assert field.set_state(5, BollState.HELD, "nozzle").holder == "nozzle"
    assert field.set_state(6, BollState.HELD, "nozzle", (0.0, 0.0, 1.0)).position_m == (0.0, 0.0, 1.0)
    assert field.held_by("nozzle") == [5, 6]
    moved = field.set_state(5, BollState.HELD, "", (0.2, 0.0, 1.0))    # held already: moves with its holder
    assert moved.position_m == (0.2, 0.0, 1.0) and field.get(6).position_m == (0.2, 0.0, 1.0)
    with pytest.raises(ValueError, match="held by 'nozzle', not 'gripper'"):
        field.set_state(5, BollState.HELD, "gripper")
    assert field.set_state(5, BollState.IN_BIN).state == BollState.IN_BIN


def test_nearest_and_within(farm):
    field = BollField(farm)
    pos = field.positions_m()
    probe = pos[4] + np.array([0.001, 0.0, 0.0])
    assert field.nearest(probe).boll_id == 4
    d = np.linalg.norm(pos - probe, axis=1)
    radius = float(np.sort(d)[3]) + 1e-9
    ids = field.within(probe, radius)
    assert ids == [int(i) for i in np.argsort(d, kind="stable")[:4]]
    field.detach(4, "nozzle")
    assert field.nearest(probe).boll_id != 4                       # only bolls still on their plants
    assert field.nearest(probe, state=BollState.HELD).boll_id == 4
    assert field.nearest(probe, state=None).boll_id == 4
    assert field.nearest(probe, max_distance_m=0.0) is None
    with pytest.raises(ValueError, match="radius_m must be >= 0"):
        field.within(probe, -1.0)
