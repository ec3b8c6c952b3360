"""Cotton-Eye's outputs over a route as report keys: rates per sim second, the no-estimate fraction."""
import pytest

from cottonsim_navigation.evaluation.vision_outputs import VisionCounts, vision_report


def test_counts_become_rates_per_sim_second_and_fractions():
    c = VisionCounts()
    for text in ["ok: straight x=161"] * 6 + ["no_estimate: ground mask missing"] * 2:
        c.add_status(text)
    c.coords = 6
    c.corrections = 30
    for v in [True, False, False, True, False]:
        c.add_verdict(v)
    r = vision_report(c, sim_duration_s=4.0)
    assert r["vision_row_centring_frames"] == 8
    assert r["vision_row_centring_per_sim_s"] == pytest.approx(2.0)
    assert r["vision_no_estimate_fraction"] == pytest.approx(0.25)
    assert r["vision_coords_per_sim_s"] == pytest.approx(1.5)
    assert r["vision_corrections"] == 30 and r["vision_corrections_per_sim_s"] == pytest.approx(7.5)
    assert r["vision_boll_verdicts_per_sim_s"] == pytest.approx(1.25)
    assert r["vision_in_reach_fraction"] == pytest.approx(0.4)


def test_nothing_counted_or_no_duration_gives_none_not_a_division_error():
    r = vision_report(VisionCounts(), sim_duration_s=0.0)
    assert r["vision_row_centring_frames"] == 0
    assert r["vision_no_estimate_fraction"] is None and r["vision_coords_per_sim_s"] is None
    assert r["vision_in_reach_fraction"] is None
