"""Unit tests of the free-space check of the beams (localization/free_space_model.py) and the helpers AMCL's
kidnap handling uses (ParticleFilter.roughen, Amcl.request_update)."""
import math

import numpy as np
import pytest

from cottonsim_navigation.core.grid import GridSpec
from cottonsim_navigation.localization.amcl import Amcl, AmclConfig
from cottonsim_navigation.localization.free_space_model import FreeSpaceCheckedField, FreeSpaceConfig
from cottonsim_navigation.localization.particle_filter import ParticleFilter, ParticleFilterConfig
from cottonsim_navigation.localization.sensor_models import (LikelihoodField, LikelihoodFieldConfig, Scan,
                                                             simulate_scan)


def hedge_map():
    """A 0.7 m thick hedge (x in [2.0, 2.7) m) across y in [-3, 3) m, open field before and behind it."""
    spec = GridSpec(0.05, 160, 160, -2.0, -4.0)
    occ = np.zeros(spec.shape, dtype=np.int8)
    occ[20:140, 80:94] = 100
    return spec, occ


def test_crossed_length_matches_the_geometry():
    spec, occ = hedge_map()
    cfg = FreeSpaceConfig(tolerance_m=0.2, check_length_m=1.0, sample_spacing_m=0.1, far_sample_spacing_m=0.0,
                          decay_length_m=0.5)
    lf = LikelihoodField(occ, spec)
    field = FreeSpaceCheckedField(lf, cfg)
    # one beam straight ahead ending 3.3 m away, i.e. behind the hedge (a see-through beam)
    scan = Scan(np.array([3.3]), np.array([0.0]))
    # checked stretch: 3.1 m back to 2.1 m, points at 3.05, 2.95, ..., 2.15 m: those in [2.0, 2.7) are
    # 2.15 .. 2.65 = 6 points -> 0.6 m crossed -> ln factor -0.6 / 0.5
    log_f = field.crossed_log_factors(np.array([[0.0, 0.0, 0.0]]), scan)
    assert log_f[0] == pytest.approx(-1.2)
    # with the coarse rest of the beam (0.35 m): 2.05 is in the hedge too (+0.35), 1.70 .. 0.30 are not
    far = FreeSpaceCheckedField(lf, FreeSpaceConfig(tolerance_m=0.2, check_length_m=1.0, sample_spacing_m=0.1,
                                                    far_sample_spacing_m=0.35, decay_length_m=0.5))
    assert far.crossed_log_factors(np.array([[0.0, 0.0, 0.0]]), scan)[0] == pytest.approx(-0.95 / 0.5)
    # capped per beam: max_crossed_m 0.3 -> -0.3 / 0.5
    capped = FreeSpaceCheckedField(lf, FreeSpaceConfig(max_crossed_m=0.3, decay_length_m=0.5))
    assert capped.crossed_log_factors(np.array([[0.0, 0.0, 0.0]]), scan)[0] == pytest.approx(-0.6)
    # turned away (beam along -x): open field, nothing crossed
    assert field.crossed_log_factors(np.array([[0.0, 0.0, math.pi]]), scan)[0] == pytest.approx(0.0)
    # disabled: the wrapped field's weights unchanged
    p = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]])
    w_on = field.weights(p, scan)
    field.enabled = False
    w_off = field.weights(p, scan)
    assert np.allclose(w_off, field.field.weights(p, scan))
    # ROS amcl's sum model (1 + sum pz^3): the one beam's pz times its own factor, not the weight times it
    factor = np.exp(field.crossed_log_factors(p, scan))
    assert factor[0] < 0.5
    assert np.allclose(w_on, 1.0 + np.cbrt(w_off - 1.0) ** 3 * factor ** 3)
    # the product model: the field's weight times the factors of all beams (the same thing for a product)
    prob = FreeSpaceCheckedField(LikelihoodField(occ, spec, LikelihoodFieldConfig(model="likelihood_field_prob")),
                                 cfg)
    assert np.allclose(prob.weights(p, scan), prob.field.weights(p, scan) * factor)
    # the wrapper passes the field's attributes through
    assert field.spec is spec and field.distance_m is field.field.distance_m


def test_free_space_check_rejects_the_pose_that_would_see_through_a_wall():
    # beams from the truth at x = 0 end on the hedge's face (2.0 m); a particle 0.5 m further ahead puts
    # those end points inside the hedge, which the likelihood field alone scores almost as well, but its
    # beams would have crossed 0.3-0.5 m of hedge first
    spec, occ = hedge_map()
    angles = np.linspace(-0.6, 0.6, 25)
    scan = simulate_scan(occ, spec, (0.0, 0.0, 0.0), angles, range_max_m=10.0)
    lf = LikelihoodField(occ, spec, LikelihoodFieldConfig(model="likelihood_field_prob"))
    checked = FreeSpaceCheckedField(lf)
    p = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]])
    w_lf = lf.weights(p, scan)
    w_fs = checked.weights(p, scan)
    assert w_lf[1] / w_lf[0] > 0.1                  # the likelihood field barely tells them apart
    assert w_fs[1] / w_fs[0] < 0.1 * w_lf[1] / w_lf[0]
    assert checked.crossed_log_factors(p[:1], scan)[0] == pytest.approx(0.0)


@pytest.mark.parametrize("name,value", [("tolerance_m", -0.1), ("check_length_m", 0.0),
                                        ("sample_spacing_m", math.nan), ("decay_length_m", True)])
def test_bad_free_space_config_names_the_parameter(name, value):
    with pytest.raises(ValueError, match=name):
        FreeSpaceConfig(**{name: value})


def test_wrapper_needs_a_likelihood_field():
    with pytest.raises(ValueError, match="LikelihoodField"):
        FreeSpaceCheckedField(object())


def test_roughen_jitters_with_the_given_spread():
    pf = ParticleFilter(ParticleFilterConfig(), np.random.default_rng(3))
    pf.set_particles(np.zeros((4000, 3)))
    pf.roughen(0.1, 0.02)
    assert np.std(pf.particles[:, 0]) == pytest.approx(0.1, rel=0.1)
    assert np.std(pf.particles[:, 1]) == pytest.approx(0.1, rel=0.1)
    assert np.std(pf.particles[:, 2]) == pytest.approx(0.02, rel=0.1)
    with pytest.raises(ValueError, match="std_yaw_rad"):
        pf.roughen(0.1, -1.0)


def test_request_update_runs_the_filter_without_motion():
    spec, occ = hedge_map()
    amcl = Amcl(AmclConfig(), np.random.default_rng(0))
    amcl.set_map(occ, spec)
    scan = simulate_scan(occ, spec, (0.0, 0.0, 0.0), np.linspace(-0.6, 0.6, 25), range_max_m=10.0)
    assert amcl.update((0.0, 0.0, 0.0), scan).updated        # the first scan always
    assert not amcl.update((0.0, 0.0, 0.0), scan).updated    # standing: no update
    amcl.request_update()
    assert amcl.update((0.0, 0.0, 0.0), scan).updated
    assert not amcl.update((0.0, 0.0, 0.0), scan).updated


def test_scan_fit_counts_beams_through_the_hedge_as_misses():
    from cottonsim_navigation.localization.quality import scan_hit_fraction
    spec, occ = hedge_map()
    field = FreeSpaceCheckedField(LikelihoodField(occ, spec))
    scan = Scan(np.full(5, 2.0), np.linspace(-0.1, 0.1, 5))     # beams end on the hedge's face
    # 0.6 m further ahead the end points lie inside the hedge: the likelihood field calls them hits ...
    assert scan_hit_fraction(field, (0.6, 0.0, 0.0), scan, 0.2) == pytest.approx(1.0)
    # ... but each beam would have crossed ~0.4 m of hedge (points 2.35 .. 2.05 m): misses
    assert np.all(field.crossed_lengths((0.6, 0.0, 0.0), scan) == pytest.approx(0.4))
    assert scan_hit_fraction(field, (0.6, 0.0, 0.0), scan, 0.2, max_crossed_m=0.3) == pytest.approx(0.0)
    assert scan_hit_fraction(field, (0.0, 0.0, 0.0), scan, 0.2, max_crossed_m=0.3) == pytest.approx(1.0)


def test_weights_skip_only_negligible_particles():
    # a spread set (a re-spread after a kidnap) in front of the hedge: the chunked check must give the
    # full product (likelihood field x free-space factor) for every particle that matters
    spec, occ = hedge_map()
    lf = LikelihoodField(occ, spec, LikelihoodFieldConfig(model="likelihood_field_prob"))
    field = FreeSpaceCheckedField(lf)
    field.CHUNK = 64
    rng = np.random.default_rng(3)
    scan = simulate_scan(occ, spec, (0.0, 0.5, 0.0), np.linspace(-1.2, 1.2, 61), range_max_m=10.0)
    parts = np.column_stack([rng.normal(0.0, 1.0, 2000), rng.normal(0.5, 1.0, 2000), rng.normal(0, 0.3, 2000)])
    full = lf.weights(parts, scan) * np.exp(field.crossed_log_factors(parts, scan))
    checked = []
    original = field.crossed_log_factors
    field.crossed_log_factors = lambda p, sc: (checked.append(len(p)), original(p, sc))[1]
    got = field.weights(parts, scan)
    big = full >= full.max() * 1e-6
    assert sum(checked) < 2000                    # some were skipped...
    assert np.allclose(got[big], full[big], rtol=1e-12, atol=0.0)   # ... none that matter
    assert np.all(got[~big] <= full.max() * 1e-6)
    assert np.all(got <= lf.weights(parts, scan) + 1e-300)         # the factor never raises a weight


def test_redraw_fraction_mixes_two_spreads():
    pf = ParticleFilter(ParticleFilterConfig(min_particles=100, max_particles=1000), np.random.default_rng(5))
    pf.init_gaussian((0.0, 0.0, 0.0), np.diag([4.0, 0.01, 0.01]))         # narrow across (y)
    assert np.std(pf.particles[:, 1]) < 0.2
    assert pf.redraw_fraction((0.0, 0.0, 0.0), np.diag([4.0, 4.0, 0.01]), 0.5) == 500
    wide = np.abs(pf.particles[:, 1]) > 0.5                                 # only round ones get there
    assert 0.35 * 1000 < wide.sum() < 0.5 * 1000                            # P(|y| > 0.5 | std 2) = 0.80
    assert np.allclose(pf.weights, 1e-3) and pf.n == 1000
    assert pf.redraw_fraction((0.0, 0.0, 0.0), np.eye(3), 0.0) == 0
    with pytest.raises(ValueError, match="fraction"):
        pf.redraw_fraction((0.0, 0.0, 0.0), np.eye(3), 1.5)
    with pytest.raises(ValueError, match="covariance"):
        pf.redraw_fraction((0.0, 0.0, 0.0), np.eye(2), 0.5)


def test_in_the_sum_model_crossing_beams_cannot_outweigh_the_scan():
    # ROS amcl's likelihood_field (1 + sum pz^3, amcl.yaml's default): at the truth 20 beams end on the
    # hedge's face and 10 see through gaps between the stems (end 3.3 m away, behind the hedge), as the
    # lidar does in the crop. A pose turned away from the hedge puts every end point in the open field and
    # crosses nothing. Multiplying the flat sum by the factor of all beams (exp(-10 * 0.7)) let that pose
    # win, and AMCL left the rows on replayed drives; per beam, the truth keeps the better weight.
    spec, occ = hedge_map()
    angles = np.linspace(-0.5, 0.5, 30)
    ranges = 2.0 / np.cos(angles)
    ranges[::3] = 3.3
    scan = Scan(ranges, angles)
    checked = FreeSpaceCheckedField(LikelihoodField(occ, spec))
    truth, turned = [0.0, 0.0, 0.0], [0.0, 0.0, math.pi]
    w = checked.weights(np.array([truth, turned]), scan)
    assert checked.crossed_log_factors(np.array([truth]), scan)[0] < -5.0       # the truth pays ...
    assert w[0] > 2.0 * w[1]                                                     # ... and still wins
