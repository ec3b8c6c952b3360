"""Row centring on synthetic sky / ground masks with a known vanishing point."""
import math

import numpy as np
import pytest

from cottonsim_common.testing import assert_config_rejects
from cottonsim_perception.data.yolo_format import polygon_to_mask
from cottonsim_perception.row_centring import (RowCentringConfig, compute_row_centring,
                                               draw_row_centring, mask_line_points)

W, H = 640, 480


def scene(vx, vy=200.0, ground_base=(0.0, 640.0), sky_top=(0.0, 640.0), gap=6.0):
    """Ground: triangle from the bottom edge to the vanishing point (vx, vy);
    sky: triangle from the top edge down to just above it (the V between two canopies)."""
    ground = polygon_to_mask(np.array([[ground_base[0], H], [ground_base[1], H], [vx, vy]]), H, W)
    sky = polygon_to_mask(np.array([[sky_top[0], 0], [sky_top[1], 0], [vx, vy - gap]]), H, W)
    return ground, sky


def expected_intersection(vx, vy=200.0, gap=6.0):
    """Hand solution: the row mid-points of a triangle lie on the line from its
    base centre (320) to its apex; ground line x = 320 + (vx - 320)(480 - y)/(480 - vy),
    sky line x = 320 + (vx - 320) y / (vy - gap); equal where
    (480 - y)/(480 - vy) = y/(vy - gap)."""
    a, b = 480.0 - vy, vy - gap
    y = 480.0 * b / (a + b)
    return 320.0 + (vx - 320.0) * y / b, y


def test_centred_symmetric_v_goes_straight():
    # Both lines are vertical through x = 320: parallel, but coincident -> straight.
    g, s = scene(320.0)
    r = compute_row_centring(g, s)
    assert r.ok and r.decision == "straight"
    assert r.intersection_px[0] == pytest.approx(320.0, abs=1.0)
    assert r.angular_z == 0.0 and r.linear_x == pytest.approx(RowCentringConfig().forward_speed_mps)


def test_small_offset_inside_dead_band_is_straight_and_finds_the_vanishing_point():
    g, s = scene(350.0)
    r = compute_row_centring(g, s)
    assert r.ok and r.decision == "straight"
    ex, ey = expected_intersection(350.0)
    assert r.intersection_px[0] == pytest.approx(ex, abs=1.0)
    assert r.intersection_px[1] == pytest.approx(ey, abs=2.0)


@pytest.mark.parametrize("vx,decision,sign", [(470.0, "right", -1), (150.0, "left", +1)])
def test_shifted_vanishing_point_turns_towards_it_capped_at_5_deg(vx, decision, sign):
    g, s = scene(vx)
    r = compute_row_centring(g, s)
    assert r.ok and r.decision == decision
    assert r.intersection_px[0] == pytest.approx(expected_intersection(vx)[0], abs=1.0)
    # REP-103: positive angular_z turns left
    assert math.copysign(1, r.angular_z) == sign
    assert abs(r.correction_rad) == pytest.approx(math.radians(5.0))
    assert abs(r.heading_error_rad) > math.radians(5.0)      # i.e. the cap was active
    assert r.angular_z == pytest.approx(RowCentringConfig().gain_per_s * r.correction_rad)


def test_uncapped_correction_is_the_bearing_of_the_intersection():
    cfg = RowCentringConfig(dead_band_px=5.0, gain_per_s=2.0, horizontal_fov_rad=math.radians(90))
    g, s = scene(340.0)
    r = compute_row_centring(g, s, cfg)
    fx = 320.0 / math.tan(math.radians(45))                  # 320 px
    expected = -math.atan((r.intersection_px[0] - 320.0) / fx)
    assert r.decision == "right"
    assert r.correction_rad == pytest.approx(expected, rel=1e-9)
    assert abs(r.correction_rad) < math.radians(5.0)
    assert r.angular_z == pytest.approx(2.0 * expected)


def test_dead_band_follows_the_original():
    # the original: 280 < x <= 360 is straight on a 640 px image. Ground symmetric
    # about x (a vertical line through x), sky leaning: they meet at x.
    cfg = RowCentringConfig()
    for x, want in ((355.0, "straight"), (366.0, "right"), (285.0, "straight"), (274.0, "left")):
        g = polygon_to_mask(np.array([[x - 100, H], [x + 100, H], [x, 240]]), H, W)
        s = polygon_to_mask(np.array([[x - 200, 0], [x + 400, 0], [x, 236]]), H, W)
        r = compute_row_centring(g, s, cfg)
        assert r.ok and r.intersection_px[0] == pytest.approx(x, abs=1.5)
        assert r.decision == want
        assert r.offset_px == pytest.approx(r.intersection_px[0] - 320.0)


def test_missing_or_tiny_masks_give_no_estimate():
    g, s = scene(400.0)
    assert compute_row_centring(g, None).reason == "no sky mask"
    assert compute_row_centring(g, np.zeros_like(s)).reason == "no sky mask"
    assert compute_row_centring(None, s).reason == "no ground mask"
    speck = np.zeros_like(g)
    speck[300:305, 300:305] = True                           # 25 px < min area
    assert compute_row_centring(speck, s).reason == "no ground mask"
    assert compute_row_centring(np.zeros_like(g), np.zeros_like(s)).reason == "empty frame"
    r = compute_row_centring(None, None)
    assert r.status == "no_estimate" and r.reason == "empty frame" and r.angular_z == 0.0


def test_bad_inputs_never_raise():
    g, s = scene(400.0)
    for ground, sky in ((g, s[:100]), (np.zeros((0, 0)), s), ("garbage", s), (g[None], s),
                        ([[1, 2], [3]], s)):
        r = compute_row_centring(ground, sky)
        assert r.status == "no_estimate" and r.reason == "empty frame"
    gn = g.astype(float)
    gn[0, 0] = np.nan                                        # NaN pixels count as background
    assert compute_row_centring(gn, s.astype(np.uint8)).ok


def test_parallel_lines_give_no_estimate():
    g = np.zeros((H, W), bool)
    g[250:, 100:200] = True                                  # vertical line x = 150
    s = np.zeros((H, W), bool)
    s[:200, 400:500] = True                                  # vertical line x = 450
    r = compute_row_centring(g, s)
    assert r.status == "no_estimate" and r.reason == "lines parallel"


def test_intersection_outside_image():
    # lines that diverge upwards: they meet far below the image
    g = polygon_to_mask(np.array([[250, H], [350, H], [200, 250]]), H, W)   # leans left going up
    s = polygon_to_mask(np.array([[400, 0], [640, 0], [640, 200]]), H, W)    # far right, leans right
    r = compute_row_centring(g, s)
    assert r.reason == "intersection outside image"


def test_band_median_ignores_a_stray_tip_row():
    m = np.zeros((100, 100), bool)
    m[20:80, 40:60] = True                                   # mid x = 50
    m[10, 95] = True                                         # a one-pixel stray at the top
    top, bottom = mask_line_points(m, band_rows=5)
    assert top[0] == pytest.approx(50.0) and bottom[0] == pytest.approx(50.0)
    top1, _ = mask_line_points(m, band_rows=1)
    assert top1[0] == pytest.approx(95.5)                     # a single row would follow it


def test_config_validation_names_the_parameter():
    assert_config_rejects(RowCentringConfig, ("max_correction_rad", 0.0), ("band_rows", 0),
                          ("dead_band_px", float("nan")))


def test_overlay_draws_without_changing_the_input():
    g, s = scene(470.0)
    img = np.zeros((H, W, 3), np.uint8)
    r = compute_row_centring(g, s)
    out = draw_row_centring(img, r, g, s)
    assert out.shape == img.shape and out.any() and not img.any()
    ix, iy = (int(round(v)) for v in r.intersection_px)
    # the magenta ring around the intersection
    ring = out[iy - 12:iy + 13, ix - 12:ix + 13]
    assert ((ring[..., 0] > 200) & (ring[..., 1] < 60) & (ring[..., 2] > 200)).any()
    bad = compute_row_centring(None, None)
    assert draw_row_centring(img, bad).shape == img.shape


def test_trace_strip_keeps_the_lane_strip_only():
    from cottonsim_perception.row_centring import trace_strip
    m = np.zeros((10, 20), bool)
    m[5:, :] = True             # near ground: full width
    m[2:5, 8:12] = True         # the lane's strip narrowing upwards
    m[1:4, 16:19] = True        # ground seen in a gap of the next row: not connected to the strip
    strip = trace_strip(m, from_bottom=True)
    assert strip[2:5, 8:12].all() and strip[5:].all()
    assert not strip[1:4, 16:19].any()
    sky = np.zeros((10, 20), bool)
    sky[0, :] = True
    sky[1:3, 5:9] = True
    sky[1:3, 12:14] = True      # a second, narrower gap: the one with more overlap wins
    assert trace_strip(sky, from_bottom=False)[1:3, 5:9].all()
    assert not trace_strip(sky, from_bottom=False)[1:3, 12:14].any()


def test_tracing_removes_the_bias_of_gaps_in_neighbouring_rows():
    # a centred V plus ground/sky seen in gaps far to the right (the open side of the field)
    g, s = scene(320.0)
    g2, s2 = g.copy(), s.copy()
    g2[195:215, 560:600] = True                # above the ground's tip (y = 200)
    s2[190:200, 560:600] = True                # below the sky's tip (y = 194)
    traced = compute_row_centring(g2, s2)
    plain = compute_row_centring(g2, s2, RowCentringConfig(trace_strips=False))
    assert traced.intersection_px[0] == pytest.approx(320.0, abs=1.0)
    assert abs(plain.intersection_px[0] - 320.0) > 5.0
    with pytest.raises(ValueError, match="trace_strips"):
        RowCentringConfig(trace_strips="yes")


def _trace_strip_row_by_row(mask, from_bottom, start_x=None):
    """trace_strip as a plain row-by-row reference (numpy argmin / argmax: the first of equals)."""
    m = np.asarray(mask, dtype=bool)
    h, w = m.shape
    out = np.zeros((h, w), dtype=bool)
    x0 = w / 2.0 if start_x is None else float(start_x)
    prev = None
    for r in (range(h - 1, -1, -1) if from_bottom else range(h)):
        d = np.diff(np.concatenate(([0], m[r].astype(np.int8), [0])))
        starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
        if starts.size == 0:
            if prev is None:
                continue
            break
        if prev is None:
            i = int(np.argmin(np.maximum(0.0, np.maximum(starts - x0, x0 - ends))))
        else:
            overlap = np.minimum(ends, prev[1]) - np.maximum(starts, prev[0])
            i = int(np.argmax(overlap))
            if overlap[i] <= 0:
                break
        out[r, starts[i]:ends[i]] = True
        prev = (starts[i], ends[i])
    return out


@pytest.mark.parametrize("seed", range(12))
def test_trace_strip_equals_the_row_by_row_reference(seed):
    from cottonsim_perception.row_centring import trace_strip
    rng = np.random.default_rng(seed)
    h, w = rng.integers(1, 60), rng.integers(1, 80)
    # blobs of a few widths, some rows empty: several runs per row, ties in gap and overlap
    mask = rng.random((h, w)) < rng.uniform(0.2, 0.9)
    mask[:, rng.integers(0, w):] &= rng.random() < 0.5
    for from_bottom in (True, False):
        for start_x in (None, 0.0, float(w), rng.uniform(0, w)):
            assert np.array_equal(trace_strip(mask, from_bottom, start_x),
                                  _trace_strip_row_by_row(mask, from_bottom, start_x))
