"""The offline pick-contacts study (harvest/pick_contacts.py) on a hand-built plant beside one lane."""
import pathlib
from types import SimpleNamespace

import numpy as np
import pytest

from cottonsim_experiments.harvest.pick_contacts import (PickContactsConfig, plan_picks, study_bolls, summarise,
                                                         sweep)
from cottonsim_experiments.harvest.reachability import robot_geometry_from_urdf
from cottonsim_manipulation.harvest.harvester import Harvester, HarvestConfig
from cottonsim_manipulation.harvest.pick_cycle import PickCycleConfig
from cottonsim_manipulation.harvest.targets import TargetFusion, TargetFusionConfig
from cottonsim_manipulation.planning.approach import ApproachConfig, plan_approach
from cottonsim_manipulation.planning.trajectory import TrajectoryConfig
from cottonsim_world.farm.model import Lane, Plant, PlantModel, PlantSkeleton

URDF = pathlib.Path(__file__).resolve().parents[3] / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf"
LANE = Lane(1, 0.0, 0.0, 3.0)          # along world y at x = 0; the plant 0.9 m east of it
BOLL_LOCAL = (-0.15, 0.0, 0.55)        # on the plant's lane-facing (west) side


@pytest.fixture(scope="module")
def robot():
    return robot_geometry_from_urdf(URDF.read_text())


def farm_with(branches=(), bolls=(BOLL_LOCAL,)):
    """One plant at (0.9, 1.5): a stem, the given branches (local start, end), bolls (local) facing the lane."""
    b = np.array(branches, dtype=float).reshape(-1, 2, 3)
    skeleton = PlantSkeleton(np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]), np.array([0.01]),
                             b[:, 0], b[:, 1], np.full(len(b), 0.005), np.zeros((0, 3)), np.zeros(0))
    model = PlantModel({}, [], np.array(bolls, dtype=float), np.full(len(bolls), 0.025), 1.0, 0.7, skeleton)
    return SimpleNamespace(plants=[Plant(0, 0, 0, 0.9, 1.5, 0.0, model)], lanes=[LANE])


def harvester_factory(robot):
    approach, trajectory = ApproachConfig(roll_samples=6), TrajectoryConfig()
    return lambda: Harvester(lambda p, n, q, stems: plan_approach(p, n, q, robot.model, stems, approach, trajectory),
                             HarvestConfig(), TargetFusion(TargetFusionConfig(confirm_observations=1)),
                             approach_config=approach, trajectory_config=trajectory)


def test_sweep_keeps_the_ends_and_steps_at_most_the_step():
    path = np.array([[0.0] * 6, [0.1, -0.25, 0, 0, 0, 0], [0.1, -0.25, 0, 0, 0, 0.05]])
    dense = sweep(path, 0.02)
    np.testing.assert_allclose(dense[0], path[0])
    np.testing.assert_allclose(dense[-1], path[-1])
    assert np.abs(np.diff(dense, axis=0)).max() <= 0.02 + 1e-12
    assert any(np.allclose(row, path[1]) for row in dense)        # through the middle waypoint


def test_a_branch_across_the_approach_is_touched_by_the_nozzle_the_bare_plant_is_not(robot):
    config = PickContactsConfig(first_plant=0, plants=1)
    bare = farm_with()
    assert study_bolls(bare, config) == [0]
    ready = PickCycleConfig().bin_joints_rad
    [clean] = plan_picks(bare, robot, harvester_factory(robot), ready, config)
    assert clean.reason == "ok" and clean.touches == () and all(d > 0 for d in clean.durations_s)
    assert clean.captured_id == 0                                  # the nozzle takes its own boll
    # a branch the robot cannot see, 7 cm out from the boll, across its approach line at its height
    x, y, z = BOLL_LOCAL
    crossed = farm_with(branches=[((x - 0.07, y - 0.1, z), (x - 0.07, y + 0.1, z))])
    [touched] = plan_picks(crossed, robot, harvester_factory(robot), ready, config)
    assert touched.reason == "ok"
    phases = {t.phase for t in touched.touches}
    assert {"approach", "retreat"} <= phases
    assert {t.part for t in touched.touches} == {"branch"} and {t.plant_id for t in touched.touches} == {0}
    assert "nozzle" in {t.link for t in touched.touches if t.phase == "approach"}
    [down] = plan_picks(bare, robot, harvester_factory(robot), ready,
                        PickContactsConfig(first_plant=0, plants=1, yaw_rad=-np.pi / 2))   # the plant on the left
    assert down.reason == "ok" and down.touches == ()
    summary = summarise([clean, touched])
    assert summary["results"] == {"ok": 2} and summary["touching_picks"] == 1
    assert summary["touching_percent_of_planned"] == 50.0
    assert summary["touches_by_part"] == {"branch": len(touched.touches)}
    assert summary["touches_by_phase"]["approach"] >= 1


def test_a_neighbour_in_front_of_the_boll_is_what_its_approach_captures(robot):
    x, y, z = BOLL_LOCAL
    farm = farm_with(bolls=(BOLL_LOCAL, (x - 0.06, y, z)))        # the second 6 cm towards the lane, in front
    config = PickContactsConfig(first_plant=0, plants=1)
    picks = {p.boll_id: p for p in plan_picks(farm, robot, harvester_factory(robot), PickCycleConfig().bin_joints_rad,
                                              config, boll_ids=[0, 1])}
    assert picks[0].reason == picks[1].reason == "ok"
    assert picks[0].captured_id == 1 and picks[1].captured_id == 1
    assert summarise(list(picks.values()))["captures"] == {"target": 1, "neighbour": 1, "neighbour_planned_clear": 1,
                                                           "none": 0}


def test_bad_set_ups_are_refused(robot):
    with pytest.raises(ValueError, match="plants"):
        PickContactsConfig(plants=0)
    with pytest.raises(ValueError, match="sweep_step_rad"):
        PickContactsConfig(sweep_step_rad=0.0)
    with pytest.raises(ValueError, match="along the lane"):
        plan_picks(farm_with(), robot, harvester_factory(robot), PickCycleConfig().bin_joints_rad,
                   PickContactsConfig(yaw_rad=0.0))
    with pytest.raises(ValueError, match="no lane 5"):
        plan_picks(farm_with(), robot, harvester_factory(robot), PickCycleConfig().bin_joints_rad,
                   PickContactsConfig(lane_index=5))
