"""Motion model statistics, likelihood-field values, resampling and the KLD bound, against hand-computed values."""
import math

import numpy as np
import pytest

from cottonsim_navigation.core.grid import GridSpec
from cottonsim_navigation.localization.motion_models import (MAX_SUBSTEPS, OdometryMotionModelConfig,
                                                              motion_parts, odometry_increment,
                                                              sample_motion_model_odometry,
                                                              split_odometry_increment)
from cottonsim_navigation.localization.particle_filter import (FreeSpaceSampler, ParticleFilter,
                                                               ParticleFilterConfig, effective_sample_size,
                                                               kld_sample_limit, systematic_resample_indices,
                                                               weight_entropy)
from cottonsim_navigation.localization.sensor_models import (LikelihoodField, LikelihoodFieldConfig, Scan,
                                                             simulate_scan, subsample_indices)


def test_motion_model_straight_line_statistics():
    # 1 m straight ahead: rot1 = rot2 = 0, trans = 1.
    # yaw = rot1' + rot2', each with variance alpha2 * 1  -> var(yaw) = 2 alpha2
    # trans' variance alpha3 * 1; x ~ trans', y ~ trans' * rot1' -> var(y) ~ alpha2
    cfg = OdometryMotionModelConfig(alpha1=0.5, alpha2=0.01, alpha3=0.04, alpha4=0.3, model="diff-corrected")
    rng = np.random.default_rng(0)
    parts = np.zeros((200000, 3))
    out = sample_motion_model_odometry(parts, (0, 0, 0), (1.0, 0, 0), cfg, rng)
    assert out[:, 0].mean() == pytest.approx(1.0 * math.exp(-0.01 / 2), abs=0.003)
    assert out[:, 0].std() == pytest.approx(math.sqrt(0.04), rel=0.03)
    assert out[:, 2].std() == pytest.approx(math.sqrt(2 * 0.01), rel=0.03)
    assert out[:, 1].std() == pytest.approx(math.sqrt(0.01), rel=0.05)
    assert np.all(parts == 0)   # input untouched


def test_motion_model_pure_rotation_and_frames():
    # pi/2 turn on the spot: trans < 1 cm -> rot1 = 0, rot2 = pi/2;
    # var(yaw) = alpha1 (pi/2)^2, var(trans) = alpha4 (pi/2)^2
    cfg = OdometryMotionModelConfig(alpha1=0.04, alpha2=0.5, alpha3=0.5, alpha4=0.01, model="diff-corrected")
    rng = np.random.default_rng(1)
    out = sample_motion_model_odometry(np.tile([2.0, 3.0, 1.0], (100000, 1)), (5, 5, 0), (5, 5, math.pi / 2),
                                       cfg, rng)
    dyaw = (out[:, 2] - (1.0 + math.pi / 2) + math.pi) % (2 * math.pi) - math.pi   # yaws wrap at pi
    assert np.mean(dyaw) == pytest.approx(0.0, abs=0.003)
    assert np.std(dyaw) == pytest.approx(0.2 * math.pi / 2, rel=0.03)
    # the displacement length is |N(0, sd)|: mean sd * sqrt(2/pi)
    sd_trans = 0.1 * math.pi / 2
    assert np.mean(np.hypot(out[:, 0] - 2, out[:, 1] - 3)) == pytest.approx(sd_trans * math.sqrt(2 / math.pi),
                                                                             rel=0.03)
    # noiseless: the odometry increment is applied in each particle's own frame
    zero = OdometryMotionModelConfig(0, 0, 0, 0)
    moved = sample_motion_model_odometry(np.array([[1.0, 1.0, math.pi / 2]]), (0, 0, 0), (1.0, 0.5, 0.3), zero)
    assert moved[0] == pytest.approx([1.0 - 0.5, 1.0 + 1.0, math.pi / 2 + 0.3])
    r1, t, r2 = odometry_increment((0, 0, 0), (-1.0, 0, 0))          # backwards step
    assert (abs(r1), t, abs(r2)) == pytest.approx((math.pi, 1.0, math.pi))
    with pytest.raises(ValueError, match="alpha3"):
        OdometryMotionModelConfig(alpha3=-1)
    with pytest.raises(ValueError, match="odom_now"):
        sample_motion_model_odometry(np.zeros((2, 3)), (0, 0, 0), (float("nan"), 0, 0))


def test_motion_model_diff_uses_the_alpha_expression_as_sd():
    # ROS amcl's "diff" model (the original's): q = alpha1 rot^2 + alpha2 trans^2 is the standard deviation.
    # A 0.25 m step with alpha 0.2: sd(rot1) = sd(rot2) = 0.2 * 0.0625 = 0.0125 rad -> sd(yaw) = 0.0125 sqrt(2);
    # sd(trans) = 0.2 * 0.0625 = 0.0125 m. The corrected form would give sqrt(0.0125) = 0.112 rad.
    cfg = OdometryMotionModelConfig(0.2, 0.2, 0.2, 0.2)
    assert cfg.model == "diff"
    out = sample_motion_model_odometry(np.zeros((200000, 3)), (0, 0, 0), (0.25, 0, 0), cfg,
                                       np.random.default_rng(4))
    assert out[:, 2].std() == pytest.approx(0.0125 * math.sqrt(2), rel=0.03)
    assert out[:, 0].std() == pytest.approx(0.0125, rel=0.03)
    corrected = sample_motion_model_odometry(np.zeros((200000, 3)), (0, 0, 0), (0.25, 0, 0),
                                             OdometryMotionModelConfig(0.2, 0.2, 0.2, 0.2, model="diff-corrected"),
                                             np.random.default_rng(4))
    assert corrected[:, 2].std() == pytest.approx(math.sqrt(0.2 * 0.0625 * 2), rel=0.03)
    with pytest.raises(ValueError, match="model"):
        OdometryMotionModelConfig(model="omni")


def test_split_odometry_increment_composes_exactly_along_the_arc():
    # a quarter circle of radius 2 m (arc 3.14 m, pi/2 rad) from a rotated start: 0.5 m / 0.5 rad limits -> 7 parts
    p0 = (1.0, -2.0, 0.7)
    c, s = math.cos(0.7), math.sin(0.7)
    rel = (2.0, 2.0, math.pi / 2)                       # end of the arc in the start's frame
    p1 = (1.0 + c * rel[0] - s * rel[1], -2.0 + s * rel[0] + c * rel[1], 0.7 + math.pi / 2)
    poses = split_odometry_increment(p0, p1, 0.5, 0.5)
    assert len(poses) == 8
    assert motion_parts(p0, p1, OdometryMotionModelConfig(max_step_m=0.5, max_step_rad=0.5)) == 7
    assert motion_parts(p0, p1, OdometryMotionModelConfig()) == 1           # no limits: one piece
    assert poses[0] == pytest.approx(p0) and poses[-1] == pytest.approx(p1)
    # every part is the same arc piece: equal chords, equal turns, all points on the circle about the centre
    chords = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    assert chords == pytest.approx(np.full(7, 2 * 2.0 * math.sin(math.pi / 28)))
    assert np.diff(poses[:, 2]) == pytest.approx(np.full(7, math.pi / 14))
    centre = (1.0 - s * 2.0, -2.0 + c * 2.0)
    assert np.hypot(poses[:, 0] - centre[0], poses[:, 1] - centre[1]) == pytest.approx(np.full(8, 2.0))
    # straight backwards, no limits, and a jump that would need more than MAX_SUBSTEPS parts
    back = split_odometry_increment((0, 0, 0), (-1.2, 0, 0), 0.5, 0.0)
    assert back[:, 0] == pytest.approx([0.0, -0.4, -0.8, -1.2]) and np.all(back[:, 1:] == 0)
    assert len(split_odometry_increment((0, 0, 0), (3, 0, 0), 0.0, 0.0)) == 2
    assert len(split_odometry_increment((0, 0, 0), (1000, 0, 0), 0.5, 0.5)) == MAX_SUBSTEPS + 1


def test_late_update_spreads_like_the_same_path_in_steps():
    # 2 m straight in one update: the diff model's sd grows with the square of the step (0.2 * 4 = 0.8 m and
    # 0.8 rad, which scatters x further);
    # split into 0.5 m parts it is that of four 0.5 m steps (sqrt(4) * 0.2 * 0.25 = 0.1 m), whatever the
    # update rate; an update on time (0.3 m) is sampled exactly as before.
    rng = np.random.default_rng(7)
    one_piece = OdometryMotionModelConfig(0.2, 0.2, 0.2, 0.2)
    split = OdometryMotionModelConfig(0.2, 0.2, 0.2, 0.2, max_step_m=0.5, max_step_rad=0.5)
    whole = sample_motion_model_odometry(np.zeros((100000, 3)), (0, 0, 0), (2.0, 0, 0), one_piece, rng)
    parts = sample_motion_model_odometry(np.zeros((100000, 3)), (0, 0, 0), (2.0, 0, 0), split, rng)
    assert whole[:, 0].std() > 0.8
    assert parts[:, 0].std() == pytest.approx(0.1, rel=0.05)
    assert parts[:, 0].mean() == pytest.approx(2.0, abs=0.01)
    stepped = np.zeros((100000, 3))
    for i in range(4):
        stepped = sample_motion_model_odometry(stepped, (0.5 * i, 0, 0), (0.5 * (i + 1), 0, 0), one_piece, rng)
    assert parts[:, 0].std() == pytest.approx(stepped[:, 0].std(), rel=0.03)
    assert parts[:, 2].std() == pytest.approx(stepped[:, 2].std(), rel=0.03)
    on_time_a = sample_motion_model_odometry(np.zeros((1000, 3)), (0, 0, 0), (0.3, 0, 0.1), split,
                                             np.random.default_rng(3))
    on_time_b = sample_motion_model_odometry(np.zeros((1000, 3)), (0, 0, 0), (0.3, 0, 0.1), one_piece,
                                             np.random.default_rng(3))
    assert np.array_equal(on_time_a, on_time_b)
    with pytest.raises(ValueError, match="max_step_m"):
        OdometryMotionModelConfig(max_step_m=float("nan"))


def test_likelihood_field_values_at_known_distances():
    spec = GridSpec(0.1, 100, 100, 0.0, 0.0)
    occ = np.zeros(spec.shape, np.int8)
    occ[:, 50] = 100                                # a wall: cells with x in [5.0, 5.1)
    cfg = LikelihoodFieldConfig(z_hit=0.8, z_rand=0.2, sigma_hit_m=0.2, likelihood_max_dist_m=1.0,
                                max_beams=30, max_range_m=10.0)
    lf = LikelihoodField(occ, spec, cfg)
    # cell centres at x = 4.65 -> 4 cells from the wall -> 0.4 m
    assert lf.distance_m[10, 46] == pytest.approx(0.4)
    assert lf.distance_m[10, 10] == pytest.approx(1.0)                 # clipped
    pz = 0.8 * math.exp(-0.4 ** 2 / (2 * 0.04)) + 0.2 / 10.0
    assert lf.pz_map[10, 46] == pytest.approx(pz)
    # one beam of 1.0 m from a robot at x=4.05 facing +x ends in the wall cell; amcl's 1 + pz^3
    scan = Scan(np.array([1.0]), np.array([0.0]))
    w = lf.weights(np.array([[4.05, 5.0, 0.0], [3.65, 5.0, 0.0]]), scan)
    assert w[0] == pytest.approx(1 + (0.8 + 0.02) ** 3)
    assert w[1] == pytest.approx(1 + pz ** 3)
    # the laser mount pose is applied: laser 0.4 m ahead, beams in a frame yawed +90 deg
    scan2 = Scan(np.array([0.6]), np.array([-math.pi / 2]), laser_pose=(0.4, 0.0, math.pi / 2))
    assert lf.weights(np.array([[4.05, 5.0, 0.0]]), scan2)[0] == pytest.approx(1 + 0.82 ** 3)
    # inf / NaN / beyond max range are skipped
    scan3 = Scan(np.array([np.inf, np.nan, 11.0]), np.zeros(3))
    assert lf.weights(np.zeros((1, 3)) + [4.0, 5.0, 0.0], scan3)[0] == pytest.approx(1.0)
    assert subsample_indices(181, 60)[[0, -1]].tolist() == [0, 180] and subsample_indices(181, 60).size == 60
    with pytest.raises(ValueError, match="sigma_hit_m"):
        LikelihoodFieldConfig(sigma_hit_m=0)
    with pytest.raises(ValueError, match="same length"):
        Scan(np.zeros(3), np.zeros(2))


def test_simulated_scan_hits_wall():
    spec = GridSpec(0.05, 200, 200, 0.0, 0.0)
    occ = np.zeros(spec.shape, np.int8)
    occ[:, 150] = 100                               # wall at x = 7.5 m
    scan = simulate_scan(occ, spec, (2.5, 5.0, 0.0), np.array([0.0, math.radians(30), math.pi]), range_max_m=20)
    assert scan.ranges_m[0] == pytest.approx(5.0, abs=0.02)
    assert scan.ranges_m[1] == pytest.approx(5.0 / math.cos(math.radians(30)), abs=0.03)
    assert np.isinf(scan.ranges_m[2])


def test_systematic_resampling_keeps_the_weight_distribution():
    rng = np.random.default_rng(3)
    w = np.array([0.5, 0.25, 0.125, 0.0625, 0.0625, 0.0])
    n = 1000
    counts = np.bincount(systematic_resample_indices(w, n, rng), minlength=w.size)
    # low-variance: each count is floor or ceil of n * w
    assert np.all(np.abs(counts - n * w) <= 1)
    # over many draws the chi-square statistic against n*w stays small
    total = np.zeros(w.size)
    for _ in range(50):
        total += np.bincount(systematic_resample_indices(w, 37, rng), minlength=w.size)
    expected = 50 * 37 * w
    chi2 = np.sum((total[w > 0] - expected[w > 0]) ** 2 / expected[w > 0])
    assert chi2 < 15.1 and total[-1] == 0           # 4 dof, p = 0.995
    assert effective_sample_size(np.ones(8)) == pytest.approx(8)
    assert weight_entropy(np.ones(4)) == pytest.approx(math.log(4))
    with pytest.raises(ValueError, match="sum to 0"):
        systematic_resample_indices(np.zeros(3), 3)


def test_kld_bound_matches_formula():
    # hand-computed: k = 10 -> (9 / 0.1) * (1 - 2/81 + sqrt(2/81) * 0.99)^3
    b = 2 / 81
    expected = math.ceil(9 / 0.1 * (1 - b + math.sqrt(b) * 0.99) ** 3)
    assert kld_sample_limit(10, 0.05, 0.99, 1, 10 ** 6) == expected
    assert kld_sample_limit(10, 0.05, 0.99, 500, 2000) == 500          # clamped up
    assert kld_sample_limit(1, 0.05, 0.99, 500, 2000) == 2000          # amcl: one bin -> max
    assert kld_sample_limit(10 ** 4, 0.05, 0.99, 500, 2000) == 2000
    ks = np.array([2, 50, 100])
    vec = kld_sample_limit(ks, 0.05, 0.99, 1, 10 ** 6)
    assert vec.tolist() == [kld_sample_limit(int(k), 0.05, 0.99, 1, 10 ** 6) for k in ks]


def test_particle_filter_adapts_size_and_clusters():
    spec = GridSpec(0.1, 200, 200, 0.0, 0.0)
    occ = np.zeros(spec.shape, np.int8)
    pf = ParticleFilter(ParticleFilterConfig(), np.random.default_rng(4))
    pf.init_gaussian((10.0, 10.0, 0.5), np.diag([1e-4, 1e-4, 1e-4]))
    assert pf.n == 2000
    n = pf.resample()
    assert n == 500                                 # all in one or two bins -> min_particles
    pf.init_uniform(FreeSpaceSampler(occ, spec))
    assert pf.resample() == 2000                    # spread over the map -> max_particles
    # two separated blobs, one with 3x the weight: the estimate is the heavy one
    a = np.random.default_rng(5).normal([2, 2, 0.1], 0.05, (300, 3))
    b = np.random.default_rng(6).normal([8, 8, -1.0], 0.05, (300, 3))
    pf.set_particles(np.vstack([a, b]), np.r_[np.full(300, 3.0), np.full(300, 1.0)])
    cl = pf.clusters()
    assert len(cl) == 2 and cl[0].weight == pytest.approx(0.75)
    assert cl[0].mean == pytest.approx([2, 2, 0.1], abs=0.02)
    assert cl[0].covariance[0, 0] == pytest.approx(0.05 ** 2, rel=0.3)
    with pytest.raises(ValueError, match="min_particles"):
        ParticleFilterConfig(min_particles=3000)


def test_recovery_injects_random_particles_when_likelihood_drops():
    spec = GridSpec(0.1, 100, 100, 0.0, 0.0)
    occ = np.zeros(spec.shape, np.int8)
    cfg = ParticleFilterConfig(min_particles=100, max_particles=400, alpha_slow=0.001, alpha_fast=0.1)
    pf = ParticleFilter(cfg, np.random.default_rng(7))
    pf.init_gaussian((5, 5, 0), np.diag([1e-4, 1e-4, 1e-4]))
    pf.update_weights(np.full(pf.n, 10.0))
    for _ in range(5):
        pf.update_weights(np.full(pf.n, 1.0))       # measurements stop fitting
    assert pf.random_fraction() > 0.3
    pf.resample(FreeSpaceSampler(occ, spec))
    far = np.hypot(pf.particles[:, 0] - 5, pf.particles[:, 1] - 5) > 1.0
    assert far.mean() > 0.2
