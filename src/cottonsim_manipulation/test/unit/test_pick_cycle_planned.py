"""The pick cycle end to end with the real approach planner, IK and collision model on a hand-built
plant row: every boll the planner can reach ends in the bin, the nozzle within the capture radius."""
import numpy as np
from hand_built_scene import GROUND_Z_M, STOW_RAD, plant_row

from cottonsim_common.kinematics.ur5e import forward_kinematics
from cottonsim_common.vacuum_capture import CaptureConfig, check_capture, nozzle_tip
from cottonsim_manipulation.harvest.pick_cycle import (
    CaptureConfirmed,
    CaptureMissed,
    PickCycle,
    PickTarget,
    RobotStopped,
    SendTrajectory,
    TrajectoryDone,
)
from cottonsim_manipulation.planning.approach import plan_approach

NOZZLE_M = 0.15


def test_every_reachable_boll_is_captured_and_binned(model):
    plants = plant_row()
    bolls = {
        1: ((0.7, 0.05, GROUND_Z_M + 0.6), (-1.0, 0.2, 0.0)),
        2: ((0.72, -0.6, GROUND_Z_M + 0.5), (-1.0, -0.3, 0.0)),
        3: ((0.68, 0.65, GROUND_Z_M + 0.75), (-1.0, 0.1, 0.0)),
        4: ((2.5, 0.0, GROUND_Z_M + 0.6), (-1.0, 0.0, 0.0)),       # far beyond the arm's reach
    }
    targets = [PickTarget(i, p, n) for i, (p, n) in bolls.items()]

    def plan(target, q):
        return plan_approach(target.position_m, target.outward, q, model, plants)

    first = {t.target_id: plan(t, STOW_RAD) for t in targets}
    reachable = [i for i, r in first.items() if r.ok]
    assert sorted(reachable) == [1, 2, 3] and first[4].reason == "unreachable"

    cycle = PickCycle(targets, STOW_RAD, plan)
    commands = cycle.start(0.0)
    now, q = 0.0, STOW_RAD.copy()
    events = [RobotStopped()]
    for _ in range(100):
        if cycle.done:
            break
        for event in events:
            commands = cycle.on_event(event, now)
        events = []
        sent = [c for c in commands if isinstance(c, SendTrajectory)]
        if sent:
            traj = sent[0].trajectory
            np.testing.assert_allclose(traj.waypoints_rad[0], q, atol=1e-9)   # starts where the arm is
            now += traj.duration_s
            q = traj.waypoints_rad[-1]
            if sent[0].purpose == "approach":
                boll, outward = bolls[cycle.current_target_id]
                tip, axis = nozzle_tip(forward_kinematics(q), NOZZLE_M)
                check = check_capture(tip, axis, boll, outward)
                assert check.distance_m <= CaptureConfig().capture_radius_m
                events.append(CaptureConfirmed() if check.captured else CaptureMissed(check.reason))
            events.append(TrajectoryDone())
        else:
            now += 0.1
            commands = cycle.tick(now)
    assert cycle.done
    result = {r.target_id: r for r in cycle.results}
    assert all(result[i].ok for i in reachable), [result[i] for i in reachable]
    assert result[4].reason == "unreachable"
    assert [r.target_id for r in cycle.results if r.ok] == [1, 2, 3]          # in the given order
    assert all(0.0 < result[i].cycle_time_s < 30.0 for i in reachable)
