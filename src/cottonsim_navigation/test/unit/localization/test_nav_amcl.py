"""AMCL on a synthetic corridor: convergence from a 0.5 m initial error and tracking a short drive."""
import math

import numpy as np
import pytest

from cottonsim_navigation.localization.amcl import Amcl, AmclConfig
from cottonsim_navigation.localization.sensor_models import Scan, simulate_scan
from nav_synthetic_maps import corridor_map


def test_amcl_converges_and_tracks_a_drive():
    spec, occ = corridor_map()
    rng = np.random.default_rng(11)
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    amcl = Amcl(AmclConfig(), rng=np.random.default_rng(12))
    amcl.set_map(occ, spec)
    truth = np.array([0.0, 1.0, math.pi / 2])
    amcl.initialise((0.4, 1.3, math.pi / 2), np.diag([0.25, 0.25, 0.07]))   # 0.5 m off
    odom = np.zeros(3)
    errors = []
    # 8 m along the corridor, odometry with 1 % scale error. (ROS amcl's "diff" noise with the original's
    # alphas is 0.0125 m per 0.25 m step: a 3 % odometry bias makes it lag ~0.16 m, by design.)
    for _ in range(80):
        truth = truth + [0.0, 0.1, 0.0]
        odom = odom + [0.101, 0.0, 0.0]
        scan = simulate_scan(occ, spec, truth, angles, range_max_m=20.0, noise_sd_m=0.01, rng=rng)
        res = amcl.update(odom, scan)
        errors.append(math.hypot(res.pose.x_m - truth[0], res.pose.y_m - truth[1]))
    assert errors[0] > 0.2
    assert max(errors[-10:]) < 0.1          # converged and tracking despite the odometry drift (0.08 m)
    assert abs(res.pose.yaw_rad - truth[2]) < 0.1
    assert 500 <= res.n_particles <= 2000
    assert res.covariance[0, 0] > 0 and res.covariance[2, 2] > 0


def test_amcl_update_thresholds_and_errors():
    spec, occ = corridor_map()
    amcl = Amcl(AmclConfig(max_particles=600), rng=np.random.default_rng(1))
    scan = Scan(np.full(10, 1.0), np.linspace(-1, 1, 10))
    with pytest.raises(ValueError, match="set_map"):
        amcl.update((0, 0, 0), scan)
    amcl.set_map(occ, spec)
    amcl.initialise((0.0, 1.0, 0.0))
    first = amcl.update((0, 0, 0), scan)
    assert first.updated and first.motion_parts == 0     # the first scan is always used, without motion
    assert not amcl.update((0.1, 0, 0), scan).updated    # < update_min_d 0.25 m
    r = amcl.update((0.3, 0, 0), scan)
    assert r.updated and r.resampled and r.motion_parts == 1
    late = amcl.update((1.4, 0, 0), scan)                 # 1.1 m since the last update: a late one
    assert late.updated and late.motion_parts == 3        # sampled in parts of <= odom_max_step_m 0.5 m
    with pytest.raises(ValueError, match="odom_pose"):
        amcl.update((np.nan, 0, 0), scan)
    with pytest.raises(ValueError, match="resample_interval"):
        AmclConfig(resample_interval=0)


def test_a_dense_re_spread_is_cut_back_to_max_particles_by_the_first_resampling():
    """initialise(n_particles=...) may draw more than max_particles (the dense re-spread after a kidnap); the
    first update's KLD resampling brings the set back within [min_particles, max_particles]."""
    spec, occ = corridor_map()
    amcl = Amcl(AmclConfig(max_particles=1500), rng=np.random.default_rng(3))
    amcl.set_map(occ, spec)
    truth = (0.0, 1.0, math.pi / 2)
    angles = np.linspace(-math.pi, math.pi, 180, endpoint=False)
    scan = simulate_scan(occ, spec, truth, angles, range_max_m=20.0)
    amcl.initialise(truth, np.diag([1.0, 0.04, 0.01]), n_particles=8000)
    assert amcl.particles.shape == (8000, 3)
    res = amcl.update((0.0, 0.0, 0.0), scan)
    assert res.updated and res.resampled
    assert 500 <= res.n_particles <= 1500 and amcl.particles.shape[0] == res.n_particles
    amcl.initialise(truth)                              # the default is max_particles
    assert amcl.particles.shape == (1500, 3)
    for bad in (0, -5, 2.5, True, "100"):
        with pytest.raises(ValueError, match="n_particles"):
            amcl.initialise(truth, n_particles=bad)
