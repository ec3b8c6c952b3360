"""Unit tests of the AMCL localised signal (localization/quality.py) against hand-computed values."""
import dataclasses
import math

import numpy as np
import pytest

from cottonsim_navigation.core.grid import GridSpec
from cottonsim_navigation.localization.amcl import Amcl, AmclConfig
from cottonsim_navigation.localization.quality import (LocalizationMonitor, LocalizationQualityConfig,
                                                       StationaryUpdatePolicy, particle_spread, scan_fit, scan_hit_fraction,
                                                       reported_covariance, respread_after_kidnap, set_covariance)
from cottonsim_navigation.localization.sensor_models import LikelihoodField, Scan


def test_spread_of_two_points_and_a_known_heading_spread():
    # two equal particles 2 m apart on x: variance 1 m^2 -> std 1 m; same heading -> 0 rad
    std_xy, std_yaw = particle_spread(np.array([[0.0, 0.0, 0.3], [2.0, 0.0, 0.3]]))
    assert std_xy == pytest.approx(1.0)
    assert std_yaw == pytest.approx(0.0, abs=1e-6)
    # headings +/-0.2 rad: mean resultant R = cos 0.2 -> sqrt(-2 ln cos 0.2)
    _, std_yaw = particle_spread(np.array([[0.0, 0.0, 0.2], [0.0, 0.0, -0.2]]))
    assert std_yaw == pytest.approx(math.sqrt(-2.0 * math.log(math.cos(0.2))))
    # weights: all mass on one particle -> no spread
    std_xy, _ = particle_spread(np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 0.0]]), np.array([1.0, 0.0]))
    assert std_xy == pytest.approx(0.0)


def test_hit_fraction_wall_in_front():
    # a wall (column of occupied cells) at x = 2.0 .. 2.1 m; beams straight ahead at 2.0 m hit it
    spec = GridSpec(0.1, 40, 40, -2.0, -2.0)
    occ = np.zeros(spec.shape, dtype=np.int8)
    occ[:, 39] = 100                                   # cells x in [1.9, 2.0)
    field = LikelihoodField(occ, spec)
    scan = Scan(np.array([1.95, 1.95, 1.95, 0.5]), np.array([0.0, 0.01, -0.01, math.pi]))
    # at the origin: 3 of 4 beams end on the wall, the backwards 0.5 m beam ends in free space
    assert scan_hit_fraction(field, (0.0, 0.0, 0.0), scan, 0.1) == pytest.approx(0.75)
    # shifted back by 1 m all beams end far from the wall
    assert scan_hit_fraction(field, (-1.0, 0.0, 0.0), scan, 0.1) == pytest.approx(0.0)


def test_scan_fit_judges_only_beams_that_end_in_the_mapped_area():
    # the wall at x = 1.9 .. 2.0 m; the cells behind x = 0.5 m (the half-plane x < 0.5) are unknown
    spec = GridSpec(0.1, 40, 40, -2.0, -2.0)
    occ = np.zeros(spec.shape, dtype=np.int8)
    occ[:, 39] = 100
    occ[:, :25] = -1
    field = LikelihoodField(occ, spec)
    # 2 beams on the wall, 1 ending in mapped free space (1.0 m ahead, 0.9 m before the wall), 3 backwards
    # into the unknown half
    scan = Scan(np.array([1.95, 1.95, 1.0, 1.0, 1.0, 1.0]), np.array([0.01, -0.01, 0.3, math.pi, 3.0, -3.0]))
    hits, judged = scan_fit(field, (0.0, 0.0, 0.0), scan, 0.1)
    assert hits == pytest.approx(2 / 6)                 # over all beams: poor
    assert judged == pytest.approx(2 / 3)               # over the judged ones: the unknown say nothing
    assert scan_hit_fraction(field, (0.0, 0.0, 0.0), scan, 0.1) == pytest.approx(hits)
    # every beam into the unknown (or beyond the map): nothing judged
    hits, judged = scan_fit(field, (0.0, 0.0, math.pi), Scan(np.array([1.0, 5.0]), np.array([0.0, 0.1])), 0.1)
    assert hits == 0.0 and math.isnan(judged)
    assert scan_fit(field, (0.0, 0.0, 0.0), Scan(np.array([np.inf]), np.array([0.0])), 0.1)[0] == 0.0


def test_no_kidnap_without_beams_that_contradict_the_map():
    mon = LocalizationMonitor(LocalizationQualityConfig(switch_after=2, relocalize_after=3))
    for _ in range(3):
        mon.update(0.05, 0.02, 0.9)
    assert mon.localized
    for _ in range(5):                                  # the scan sees (almost) nothing the map knows
        mon.update(0.05, 0.02, 0.1, math.nan)
        mon.update(0.05, 0.02, 0.1, 0.8)                # ... or what it judges fits
    assert not mon.localized and not mon.kidnapped and not mon.suspect
    for _ in range(3):                                  # beams in mapped free space: a kidnap
        mon.update(0.05, 0.02, 0.1, 0.2)
    assert mon.kidnapped


def test_monitor_hysteresis_and_kidnap():
    cfg = LocalizationQualityConfig(switch_after=2, relocalize_after=3)
    mon = LocalizationMonitor(cfg)
    assert mon.update(0.05, 0.02, 0.9) is False          # one good update is not enough
    assert mon.update(0.05, 0.02, 0.9) is True
    assert mon.update(0.05, 0.02, 0.1) is True           # one poor fit: still localised
    assert not mon.kidnapped
    assert mon.update(0.05, 0.02, 0.1) is False          # two: not localised
    assert not mon.kidnapped and mon.suspect              # ... and a kidnap is suspected
    mon.update(0.05, 0.02, 0.1)
    assert mon.kidnapped                                  # tight but wrong three times
    mon.reset()
    assert not mon.kidnapped and mon.localized is False
    mon.update(2.0, 0.5, 0.1)                             # wide spread: not a kidnap
    mon.update(2.0, 0.5, 0.1)
    mon.update(2.0, 0.5, 0.1)
    assert not mon.kidnapped


@pytest.mark.parametrize("field,value", [("max_std_xy_m", 0.0), ("min_hit_fraction", 1.5), ("switch_after", 0),
                                         ("relocalize_after", -1), ("hit_distance_m", float("nan")),
                                         ("stationary_update_period_s", -0.5), ("roughen_std_xy_m", math.inf),
                                         ("relocalize_particles", -1), ("relocalize_particles", 2.5),
                                         ("relocalize_particles", True)])
def test_bad_config_names_the_parameter(field, value):
    with pytest.raises(ValueError, match=field):
        LocalizationQualityConfig(**{field: value})


def test_set_covariance_covers_all_clusters():
    # two tight groups 4 m apart on y, equal weight: y variance 4 m^2 (each 2 m from the mean), x 0
    p = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 4.0, 0.0], [1.0, 4.0, 0.0]])
    cov = set_covariance(p)
    assert cov[1, 1] == pytest.approx(4.0)
    assert cov[0, 0] == pytest.approx(0.0)
    assert cov[2, 2] == pytest.approx(0.0, abs=1e-9)
    # weighted towards one group: p(1-p) * d^2 = 0.25 * 0.75 * 16
    cov = set_covariance(p, np.array([0.125, 0.125, 0.375, 0.375]))
    assert cov[1, 1] == pytest.approx(0.1875 * 16.0)
    with pytest.raises(ValueError, match="weights"):
        set_covariance(p, np.array([1.0, -1.0, 0.0, 0.0]))


def test_reported_covariance_is_never_tight_while_unverified():
    # a set that agrees (std 0.1 m on x, 0.05 on y, ~0 rad) on a pose, AMCL's cluster covariance tighter still
    p = np.array([[0.9, 0.05, 0.0], [1.1, -0.05, 0.0], [0.9, -0.05, 0.0], [1.1, 0.05, 0.0]])
    amcl_cov = np.diag([0.001, 0.001, 0.0001])
    config = LocalizationQualityConfig(relocalize_std_xy_m=2.0, relocalize_std_across_m=0.5,
                                       relocalize_std_yaw_rad=0.3, min_hit_fraction=0.6)
    # localised: AMCL's own covariance, unchanged
    np.testing.assert_array_equal(reported_covariance(amcl_cov, p, None, True, 0.9, 0.0, config), amcl_cov)
    # not localised but the scan fits (only the spread test failed): the whole set's spread
    cov = reported_covariance(amcl_cov, p, None, False, 0.9, 0.0, config)
    assert cov[0, 0] == pytest.approx(0.01)
    assert cov[1, 1] == pytest.approx(0.0025)
    assert cov[2, 2] == pytest.approx(0.0001)
    # not localised and the scan does not fit: at least the re-spread (2 m along the heading, 0.5 m across)
    cov = reported_covariance(amcl_cov, p, None, False, 0.3, math.pi / 2, config)
    assert cov[0, 0] == pytest.approx(0.25)
    assert cov[1, 1] == pytest.approx(4.0)
    assert cov[2, 2] == pytest.approx(0.09)
    # the input is not modified
    assert amcl_cov[0, 0] == 0.001
    with pytest.raises(ValueError, match="hit_fraction"):
        reported_covariance(amcl_cov, p, None, False, 1.5, 0.0, config)
    with pytest.raises(ValueError, match="filter_covariance"):
        reported_covariance(np.full((3, 3), np.nan), p, None, False, 0.5, 0.0, config)


def test_stationary_policy_asks_for_updates_only_when_needed():
    pol = StationaryUpdatePolicy(LocalizationQualityConfig(stationary_update_period_s=0.5, min_hit_fraction=0.6))
    # localised with a good fit: never
    assert pol.decide(0.0, True, 0.9) == (False, False)
    # localised, poor fit: an update (no jitter), then not again before 0.5 s have passed
    assert pol.decide(1.0, True, 0.3) == (True, False)
    assert pol.decide(1.2, True, 0.3) == (False, False)
    assert pol.decide(1.5, True, 0.3) == (True, False)
    # not localised and not re-localising (e.g. the start, before any motion): never
    assert pol.decide(3.0, False, None) == (False, False)
    # re-localising after a kidnap: updates with jitter at the period, until localised again
    pol.start_relocalizing()
    assert pol.decide(4.0, False) == (True, True)
    assert pol.decide(4.1, False) == (False, False)
    assert pol.decide(4.6, False) == (True, True)
    assert pol.decide(5.2, True, 0.9) == (False, False)
    assert not pol.relocalizing
    # a clock jump back (sim restarted) does not block the updates
    pol.start_relocalizing()
    assert pol.decide(0.1, False) == (True, True)
    # not localised any more but a kidnap is suspected (tight set, poor fit): updates go on (no jitter) so
    # that the standing robot's kidnap is confirmed
    sus = StationaryUpdatePolicy(LocalizationQualityConfig(stationary_update_period_s=0.5))
    assert sus.decide(7.0, False, None, suspect=True) == (True, False)
    assert sus.decide(7.2, False, None, suspect=True) == (False, False)
    assert sus.decide(7.6, False, None, suspect=False) == (False, False)
    off = StationaryUpdatePolicy(LocalizationQualityConfig(stationary_update_period_s=0.0))
    off.start_relocalizing()
    assert off.decide(10.0, False) == (False, False)


def test_relocalize_covariance_along_and_across_the_heading():
    cfg = LocalizationQualityConfig(relocalize_std_xy_m=2.0, relocalize_std_across_m=0.5, relocalize_std_yaw_rad=0.3)
    # heading along +x: x is "along" (2 m), y "across" (0.5 m)
    assert np.allclose(cfg.relocalize_covariance(0.0), np.diag([4.0, 0.25, 0.09]))
    # heading along +y: swapped
    assert np.allclose(cfg.relocalize_covariance(math.pi / 2), np.diag([0.25, 4.0, 0.09]))
    # 45 deg: variance along the heading direction u is u^T C u = 4, across 0.25
    c = cfg.relocalize_covariance(math.pi / 4)[:2, :2]
    u, v = np.array([1.0, 1.0]) / math.sqrt(2), np.array([-1.0, 1.0]) / math.sqrt(2)
    assert u @ c @ u == pytest.approx(4.0) and v @ c @ v == pytest.approx(0.25)
    # 0 = round (the old behaviour), whatever the heading
    assert np.allclose(LocalizationQualityConfig(relocalize_std_xy_m=2.0).relocalize_covariance(1.0)[:2, :2],
                       4.0 * np.eye(2))
    with pytest.raises(ValueError, match="relocalize_std_across_m"):
        LocalizationQualityConfig(relocalize_std_across_m=-1.0)
    with pytest.raises(ValueError, match="relocalize_round_fraction"):
        LocalizationQualityConfig(relocalize_round_fraction=1.2)
    with pytest.raises(ValueError, match="yaw_rad"):
        cfg.relocalize_covariance(float("nan"))


def test_collapsed_set_has_zero_heading_spread_not_a_math_error():
    # five particles at the same yaw -2.9 with equal weights: the mean resultant length rounds to
    # 1.0000000000000002 (found by search); -2 ln R was negative and its square root raised
    # "math domain error" in the amcl node's scan callback
    from cottonsim_navigation.localization.particle_filter import ParticleFilter, mean_resultant_length

    yaws, w = np.full(5, -2.9), np.full(5, 0.2)
    assert math.hypot(float(w @ np.cos(yaws)), float(w @ np.sin(yaws))) > 1.0     # the rounding case
    assert mean_resultant_length(yaws, w) == 1.0
    parts = np.column_stack([np.arange(5.0), np.zeros(5), yaws])
    assert particle_spread(parts)[1] == 0.0
    assert set_covariance(parts)[2, 2] == 0.0
    pf = ParticleFilter()
    pf.set_particles(parts)
    assert pf.estimate().covariance[2, 2] == 0.0


def test_respread_after_kidnap_draws_the_configured_set():
    """The node's re-spread: relocalize_particles around the pose, narrow across its heading; with
    relocalize_round_fraction a share re-drawn round."""
    amcl = Amcl(AmclConfig(), rng=np.random.default_rng(4))
    pose = (3.0, -4.5, 0.0)
    cfg = LocalizationQualityConfig(relocalize_std_xy_m=2.0, relocalize_std_across_m=0.5, relocalize_particles=6000)
    respread_after_kidnap(amcl, pose, cfg)
    p = amcl.particles
    assert p.shape == (6000, 3)
    assert abs(p[:, 0].std() - 2.0) < 0.1 and abs(p[:, 1].std() - 0.5) < 0.05    # along x, across y
    respread_after_kidnap(amcl, pose, dataclasses.replace(cfg, relocalize_particles=0, relocalize_round_fraction=0.5))
    p = amcl.particles
    assert p.shape == (2000, 3)                                  # 0 = max_particles
    assert p[:, 1].std() > 1.0                                   # half of them round (2 m across too)
