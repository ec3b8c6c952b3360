"""hector_gazebo GPS geodesy and the GPS drift/noise model."""
import math
import pathlib
import os

import numpy as np
import pytest

from cottonsim_world.geodesy import GpsNoiseConfig, GpsNoiseModel, HectorGeodesy

# the original CottonSim GPS route, committed with the navigation package
WAYPOINTS = str(pathlib.Path(__file__).resolve().parents[3] / "cottonsim_navigation" / "config" / "waypoints"
                / "original_gps_waypoints.txt")


def test_radii_match_the_originals_numbers():
    g = HectorGeodesy()
    assert g.radius_north_m == pytest.approx(6372845.0, abs=1.0)
    assert g.radius_east_m == pytest.approx(4116378.0, abs=1.0)
    # independent check of R_E: a cos(lat) / sqrt(1 - e2 sin^2 lat)
    a, f = 6378137.0, 1 / 298.257223563
    e2 = f * (2 - f)
    lat = math.radians(49.9)
    assert g.radius_east_m == pytest.approx(a * math.cos(lat) / math.sqrt(1 - e2 * math.sin(lat) ** 2), rel=1e-12)


def test_spawn_maps_to_the_originals_fix():
    lat, lon, alt = HectorGeodesy().world_to_geodetic(-6.0, 1.0, 0.2)
    assert lat == pytest.approx(49.899946, abs=1e-6)
    assert lon == pytest.approx(8.899986, abs=1e-6)
    assert alt == pytest.approx(0.2)
    assert isinstance(lat, float)


def test_heading_zero_is_x_north_y_west_and_ninety_is_enu():
    g0 = HectorGeodesy()
    lat, lon, _ = g0.world_to_geodetic(10.0, 0.0)
    assert lat > 49.9 and lon == pytest.approx(8.9)
    lat, lon, _ = g0.world_to_geodetic(0.0, 10.0)
    assert lon < 8.9 and lat == pytest.approx(49.9)       # +y is west
    g90 = HectorGeodesy(reference_heading_deg=90.0)
    lat, lon, _ = g90.world_to_geodetic(10.0, 0.0)       # x east
    assert lon > 8.9 and lat == pytest.approx(49.9, abs=1e-12)
    assert math.radians(lon - 8.9) * g90.radius_east_m == pytest.approx(10.0)
    lat, lon, _ = g90.world_to_geodetic(0.0, 10.0)       # y north
    assert lat > 49.9 and lon == pytest.approx(8.9, abs=1e-12)
    assert math.radians(lat - 49.9) * g90.radius_north_m == pytest.approx(10.0)


@pytest.mark.parametrize("heading", [0.0, 37.0, 90.0, -120.0])
def test_vectorised_equals_scalar_and_round_trip(heading):
    g = HectorGeodesy(reference_heading_deg=heading, reference_altitude_m=12.0)
    rng = np.random.default_rng(1)
    xyz = rng.uniform(-50, 50, size=(20, 3))
    lat, lon, alt = g.world_to_geodetic(xyz[:, 0], xyz[:, 1], xyz[:, 2])
    for i in range(0, 20, 5):
        s = g.world_to_geodetic(*xyz[i])
        assert s == pytest.approx((lat[i], lon[i], alt[i]), abs=1e-12)
    x, y, z = g.geodetic_to_world(lat, lon, alt)
    np.testing.assert_allclose(np.stack([x, y, z], axis=1), xyz, atol=1e-7)


def test_original_waypoint_file_round_trips():
    ll = np.loadtxt(WAYPOINTS)
    assert ll.shape == (30, 2)
    g = HectorGeodesy()
    x, y, _ = g.geodetic_to_world(ll[:, 0], ll[:, 1])
    lat, lon, _ = g.world_to_geodetic(x, y)
    np.testing.assert_allclose(lat, ll[:, 0], atol=1e-12)
    np.testing.assert_allclose(lon, ll[:, 1], atol=1e-12)
    # the waypoints lie in the farm's area: x west of 0, y between 3 and 28 m
    assert np.all(x < 0) and np.all((y > 3) & (y < 28))


@pytest.mark.parametrize("ref_lon", [179.9999, -179.9999])
def test_longitudes_wrap_at_the_antimeridian(ref_lon):
    """A farm on the antimeridian: fixes stay in [-180, 180] deg and map back to the same world points."""
    g = HectorGeodesy(reference_latitude_deg=-17.0, reference_longitude_deg=ref_lon)
    y = np.array([-40.0, -5.0, 0.0, 5.0, 40.0])                       # world y west
    lat, lon, _ = g.world_to_geodetic(np.zeros(5), y)
    assert np.all((lon >= -180.0) & (lon <= 180.0))
    assert np.any(np.sign(lon) != np.sign(ref_lon))                     # some points lie across it
    for i in range(5):
        assert g.world_to_geodetic(0.0, float(y[i]), 0.0)[1] == lon[i]
    x2, y2, _ = g.geodetic_to_world(lat, lon)
    np.testing.assert_allclose(y2, y, atol=1e-7)
    np.testing.assert_allclose(x2, 0.0, atol=1e-7)


def test_bad_input_raises():
    with pytest.raises(ValueError, match="reference_latitude_deg"):
        HectorGeodesy(reference_latitude_deg=90.0)
    with pytest.raises(ValueError, match="reference_heading_deg"):
        HectorGeodesy(reference_heading_deg=float("nan"))
    with pytest.raises(ValueError, match="x_m"):
        HectorGeodesy().world_to_geodetic(float("nan"), 0.0)
    with pytest.raises(ValueError, match="latitude_deg"):
        HectorGeodesy().geodetic_to_world(95.0, 8.9)


def test_noise_defaults_and_determinism():
    c = GpsNoiseConfig()
    assert c.drift_m == (0.0001,) * 3 and c.gaussian_noise_m == (0.0,) * 3
    a, b = GpsNoiseModel(GpsNoiseConfig(seed=4, drift_m=0.5, drift_frequency_hz=0.1)), \
        GpsNoiseModel(GpsNoiseConfig(seed=4, drift_m=0.5, drift_frequency_hz=0.1))
    p = np.array([1.0, 2.0, 0.0])
    ra = np.array([a.apply(p, 0.025) for _ in range(50)])
    rb = np.array([b.apply(p, 0.025) for _ in range(50)])
    np.testing.assert_array_equal(ra, rb)
    a.reset()
    np.testing.assert_array_equal(np.array([a.apply(p, 0.025) for _ in range(50)]), ra)
    other = GpsNoiseModel(GpsNoiseConfig(seed=5, drift_m=0.5, drift_frequency_hz=0.1))
    assert not np.allclose([other.apply(p, 0.025) for _ in range(50)], ra)


def test_noise_statistics():
    # white noise only: mean offset, std as configured
    m = GpsNoiseModel(GpsNoiseConfig(offset_m=(1.0, 0.0, -1.0), drift_m=0.0, gaussian_noise_m=(0.2, 0.2, 0.0), seed=1))
    e = np.array([m.update(0.025) for _ in range(4000)])
    np.testing.assert_allclose(e.mean(axis=0), [1.0, 0.0, -1.0], atol=0.02)
    np.testing.assert_allclose(e.std(axis=0), [0.2, 0.2, 0.0], atol=0.01)
    # drift: stationary std = drift_m (fast process sampled sparsely)
    d = GpsNoiseModel(GpsNoiseConfig(drift_m=0.3, drift_frequency_hz=1.0, seed=2))
    e = np.array([d.update(5.0) for _ in range(4000)])
    np.testing.assert_allclose(e.std(axis=0), 0.3, rtol=0.08)
    # drift is slow: consecutive 40 Hz errors are strongly correlated
    s = GpsNoiseModel(GpsNoiseConfig(drift_m=1.0, drift_frequency_hz=0.01, seed=3))
    e = np.array([s.update(0.025) for _ in range(2000)])
    step_std = math.sqrt(1 - math.exp(-2 * 0.01 * 0.025))   # ~0.022 m per fix, vs 1 m stationary
    assert np.std(np.diff(e, axis=0)) == pytest.approx(step_std, rel=0.1)


def test_noise_bad_input():
    with pytest.raises(ValueError, match="drift_m"):
        GpsNoiseConfig(drift_m=-1.0)
    with pytest.raises(ValueError, match="gaussian_noise_m"):
        GpsNoiseConfig(gaussian_noise_m=(0.1, 0.2))
    m = GpsNoiseModel()
    with pytest.raises(ValueError, match="dt_s"):
        m.update(-0.1)
    with pytest.raises(ValueError, match="position_m"):
        m.apply([1.0, 2.0], 0.1)
    for bad in (np.array([1.0, np.nan, 0.0]), [1.0, np.inf, 0.0]):     # the float64 fast path and the general one
        with pytest.raises(ValueError, match="position_m"):
            m.apply(bad, 0.1)


@pytest.mark.parametrize("heading", [0.0, 37.0, -120.0])
def test_float_fast_path_is_bit_identical_to_the_array_path(heading):
    """Three floats take the plain-float path; it must give numpy's results exactly."""
    g = HectorGeodesy(reference_heading_deg=heading, reference_altitude_m=3.5)
    xyz = np.random.default_rng(2).uniform(-60, 60, size=(200, 3))
    lat, lon, alt = g.world_to_geodetic(xyz[:, 0], xyz[:, 1], xyz[:, 2])
    for i in range(len(xyz)):
        fast = g.world_to_geodetic(float(xyz[i, 0]), float(xyz[i, 1]), float(xyz[i, 2]))
        assert all(type(v) is float for v in fast)
        assert fast == (lat[i], lon[i], alt[i])
    with pytest.raises(ValueError, match="z_m"):
        g.world_to_geodetic(1.0, 2.0, float("inf"))


def test_noise_model_matches_the_vector_formula_exactly():
    """The float implementation of GpsNoiseModel against the Gauss-Markov formula on numpy 3-vectors."""
    cfg = GpsNoiseConfig(offset_m=(0.1, -0.2, 0.3), drift_m=(0.5, 0.4, 0.3), drift_frequency_hz=(0.1, 0.2, 0.3),
                         gaussian_noise_m=(0.05, 0.06, 0.07), seed=9)
    model = GpsNoiseModel(cfg)
    rng = np.random.default_rng(9)
    drift = np.zeros(3)
    freq, std, off, noise = (np.array(v) for v in (cfg.drift_frequency_hz, cfg.drift_m, cfg.offset_m,
                                                     cfg.gaussian_noise_m))
    p = np.array([-6.0, 1.0, 0.2])
    for dt in [0.025] * 5 + [0.05, 0.025, 0.0, 1.0]:
        decay = np.exp(-freq * dt)
        drift = drift * decay + std * np.sqrt(1.0 - decay ** 2) * rng.standard_normal(3)
        expected = p + (off + drift + noise * rng.standard_normal(3))
        got = model.apply(p, dt)
        assert got.dtype == np.float64 and np.array_equal(got, expected)
        assert np.array_equal(model.current_drift_m, drift)
