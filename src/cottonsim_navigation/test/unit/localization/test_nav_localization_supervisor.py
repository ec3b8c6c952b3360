"""The amcl node's policy without ROS (localization/supervisor.py): an uncertain start is no kidnap, a real
kidnap of a localised robot is detected, re-spread and recovered."""
import math

import numpy as np
import pytest

from cottonsim_navigation.core.grid import GridSpec
from cottonsim_navigation.localization.amcl import Amcl, AmclConfig
from cottonsim_navigation.localization.quality import LocalizationQualityConfig
from cottonsim_navigation.localization.sensor_models import Scan, simulate_scan
from cottonsim_navigation.localization.supervisor import LocalizationSupervisor, SupervisorConfig
from nav_synthetic_maps import field_map

ANGLES = np.linspace(-math.pi, math.pi, 360, endpoint=False)
UP = math.pi / 2
SCAN_PERIOD_S = 0.1
# amcl_farm.yaml's choices (the product laser model, the re-spread narrow across the heading)
FARM = (AmclConfig(laser_model_type="likelihood_field_prob"),
        SupervisorConfig(quality=LocalizationQualityConfig(relocalize_std_across_m=0.5)))


def headland_field_map():
    """nav_synthetic_maps.field_map (two rows of plants at x = -0.9, 0.9 m from y = 0.7 m) with 8 m of open
    headland in front of the rows (y from -8 m)."""
    spec, occ = field_map()
    pad = int(round(4.0 / spec.resolution_m))
    return (GridSpec(spec.resolution_m, spec.width, spec.height + pad, spec.origin_x_m, spec.origin_y_m - 4.0),
            np.vstack([np.zeros((pad, spec.width), occ.dtype), occ]))


def supervisor(configs=FARM, seed=0):
    spec, occ = headland_field_map()
    amcl_config, sup_config = configs
    sup = LocalizationSupervisor(Amcl(amcl_config, np.random.default_rng(seed)), sup_config)
    sup.set_map(occ, spec)
    return sup, spec, occ


def scan_at(spec, occ, truth, rng, clutter=0.0):
    """A 360-beam scan from ``truth``; ``clutter``: share of the beams replaced by short unmapped returns
    (0.5-1.5 m: tall grass, dust) -- such a scan fits the map poorly wherever the robot is."""
    scan = simulate_scan(occ, spec, truth, ANGLES, range_max_m=8.0, noise_sd_m=0.01, rng=rng)
    ranges = scan.ranges_m.copy()
    k = rng.random(ranges.size) < clutter
    ranges[k] = rng.uniform(0.5, 1.5, int(k.sum()))
    return Scan(ranges, ANGLES, range_max_m=8.0)


def drive(sup, spec, occ, truth, odom, t, steps, dy=0.1, clutter=0.0, rng=None):
    """``steps`` scans while the robot moves ``dy`` along +y per scan (odometry sees the motion)."""
    steps_out = []
    for _ in range(steps):
        truth = truth + [0.0, dy, 0.0]
        odom = odom + [dy, 0.0, 0.0]       # odom frame: started facing its +x
        t += SCAN_PERIOD_S
        step = sup.step(t, odom, scan_at(spec, occ, truth, rng, clutter))
        steps_out.append((step, truth.copy()))
    return truth, odom, t, steps_out


def error_m(step, truth):
    return math.hypot(step.result.pose.x_m - truth[0], step.result.pose.y_m - truth[1])


def test_an_uncertain_start_with_a_poorly_fitting_scan_is_no_kidnap():
    # the robot starts 0.3 m from its initial pose (amcl's 0.5 m spread) in front of the rows; 30 % of
    # its beams see unmapped clutter: the set contracts (tight) while the scan fit stays below 0.6. Before
    # the supervisor armed the kidnap detection only once localised, this re-spread the set (a "kidnap").
    sup, spec, occ = supervisor()
    rng = np.random.default_rng(1)
    truth, odom = np.array([0.0, -5.0, UP]), np.zeros(3)
    sup.initialise((0.2, -4.8, UP), relocalize=False)
    truth, odom, t, steps = drive(sup, spec, occ, truth, odom, 0.0, 35, clutter=0.3, rng=rng)
    updates = [(s, tr) for s, tr in steps if s.updated]
    assert len(updates) >= 8
    assert any(s.std_xy_m <= 0.15 and s.hit_fraction < 0.6 for s, _ in updates)   # tight, poor fit
    assert sup.kidnaps == 0 and not any(s.kidnapped for s, _ in updates)
    assert not sup.armed and not sup.localized
    assert error_m(*updates[-1]) < 0.2
    # the clutter clears: localised, and from then on armed
    truth, odom, t, steps = drive(sup, spec, occ, truth, odom, t, 10, rng=rng)
    assert sup.localized and sup.armed and sup.kidnaps == 0
    assert error_m(*steps[-1]) < 0.15


@pytest.mark.parametrize("seed", [0, 1])
def test_a_localized_robot_carried_toward_the_rows_is_detected_and_recovers(seed):
    sup, spec, occ = supervisor(seed=seed)
    rng = np.random.default_rng(10 + seed)
    truth, odom = np.array([0.0, -5.0, UP]), np.zeros(3)
    sup.initialise((0.05, -5.05, UP), np.diag([0.01, 0.01, 0.003]), relocalize=False)     # a known start
    truth, odom, t, steps = drive(sup, spec, occ, truth, odom, 0.0, 10, rng=rng)
    assert sup.localized and sup.armed and error_m(*steps[-1]) < 0.1
    # kidnap: the standing robot is carried 3 m forward, from 4.7 m to 1.7 m before the plants (their ends in
    # view: recoverable, docs/map_experiment.md "Kidnap"); odometry does not see it
    truth = truth + [0.0, 3.0, 0.0]
    truth, odom, t, steps = drive(sup, spec, occ, truth, odom, t, 150, dy=0.0, rng=rng)
    kidnapped = [i for i, (s, _) in enumerate(steps) if s.kidnapped]
    assert len(kidnapped) == 1 and sup.kidnaps == 1
    k_step, k_truth = steps[kidnapped[0]]
    assert not k_step.localized and error_m(k_step, k_truth) > 2.5
    assert k_step.particles.shape[0] == sup.config.quality.relocalize_particles      # the dense re-spread
    back = [i for i, (s, _) in enumerate(steps) if i > kidnapped[0] and s.localized]
    assert back, "not localised again after the re-spread"
    assert error_m(*steps[back[0]]) < 0.15
    assert sup.armed


def test_a_standing_robot_that_lost_its_localized_signal_regains_it():
    # localised, then a few scans with clutter turn the signal off (no kidnap: too short); the navigator
    # stops the robot. The filter must go on updating while it stands, or the signal never comes back.
    sup, spec, occ = supervisor()
    rng = np.random.default_rng(4)
    truth, odom = np.array([0.0, -5.0, UP]), np.zeros(3)
    sup.initialise((0.05, -5.05, UP), np.diag([0.01, 0.01, 0.003]), relocalize=False)
    truth, odom, t, _ = drive(sup, spec, occ, truth, odom, 0.0, 10, rng=rng)
    assert sup.localized
    truth, odom, t, steps = drive(sup, spec, occ, truth, odom, t, 10, dy=0.0, clutter=0.8, rng=rng)
    assert not sup.localized and sup.kidnaps == 0
    truth, odom, t, steps = drive(sup, spec, occ, truth, odom, t, 20, dy=0.0, rng=rng)
    assert sup.localized and sup.kidnaps == 0
    assert error_m(*steps[-1]) < 0.1


def test_reinitialising_disarms_the_kidnap_detection():
    sup, spec, occ = supervisor()
    sup.armed = True
    sup.initialise((0.0, -3.0, UP))
    assert not sup.armed and sup.stationary.relocalizing and not sup.localized
    sup.armed = True
    sup.global_localization()
    assert not sup.armed and sup.stationary.relocalizing


def test_bad_input_names_the_problem():
    with pytest.raises(ValueError, match="free_space_mode"):
        SupervisorConfig(free_space_mode="sometimes")
    with pytest.raises(ValueError, match="quality"):
        SupervisorConfig(quality={"max_std_xy_m": 0.1})
    with pytest.raises(ValueError, match="Amcl"):
        LocalizationSupervisor("amcl")
    sup = LocalizationSupervisor(Amcl(AmclConfig()))
    with pytest.raises(ValueError, match="set_map"):
        sup.step(0.0, (0.0, 0.0, 0.0), Scan(np.ones(3), np.zeros(3)))
    sup, _, _ = supervisor()
    with pytest.raises(ValueError, match="now_s"):
        sup.step(math.nan, (0.0, 0.0, 0.0), Scan(np.ones(3), np.zeros(3)))
