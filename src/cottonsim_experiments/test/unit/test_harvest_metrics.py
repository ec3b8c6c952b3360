"""The harvest's figures (harvest/metrics.py) from hand-made records with known answers."""
import pytest

from cottonsim_experiments.harvest.metrics import BollOutcome, RunTotals, harvest_figures


def outcomes():
    """10 open bolls: 8 reachable; of those 7 detected, 6 attempted, 5 picked, 4 in the bin; one binned boll
    was not reachable by the evaluation's rule (it still counts for the field)."""
    picked = dict(reachable=True, detected=True, attempted=True, picked=True)
    return [
        BollOutcome(0, **picked, in_bin=True, cycle_time_s=4.0, localization_error_m=0.004),
        BollOutcome(1, **picked, in_bin=True, cycle_time_s=5.0, localization_error_m=0.006),
        {"boll_id": 2, **picked, "in_bin": True, "cycle_time_s": 6.0, "localization_error_m": 0.008},
        BollOutcome(3, **picked, in_bin=True, cycle_time_s=20.0, localization_error_m=0.030),
        BollOutcome(4, **picked, in_bin=False, reason="dropped", localization_error_m=0.010),
        BollOutcome(5, reachable=True, detected=True, attempted=True, reason="capture_missed",
                    localization_error_m=0.5),
        BollOutcome(6, reachable=True, detected=True, reason=""),
        BollOutcome(7, reachable=True),
        BollOutcome(8),
        BollOutcome(9, detected=True, attempted=True, picked=True, in_bin=True, cycle_time_s=7.0),
    ]


def test_counts_funnel_and_successes():
    f = harvest_figures(outcomes(), RunTotals(field_time_s=1800.0, picking_time_s=60.0, arm_leaf_contacts=3))
    assert (f["open_bolls"], f["reachable"], f["detected"], f["attempted"], f["picked"], f["in_bin"]) == \
        (10, 8, 8, 7, 6, 5)
    funnel = {s["stage"]: (s["count"], s["percent_of_previous"]) for s in f["funnel"]}
    assert funnel["reachable"] == (8, None)
    assert funnel["localisation"] == (7, pytest.approx(87.5))       # detected among the reachable
    assert funnel["pick"] == (6, pytest.approx(600 / 7))            # captured / attempted
    assert funnel["bin"] == (5, pytest.approx(500 / 6))             # binned / captured
    assert f["harvest_success_percent"] == pytest.approx(50.0)      # 4 of the 8 reachable
    assert f["field_harvest_percent"] == pytest.approx(50.0)        # 5 of the 10 open
    assert f["miss_reasons"] == {"capture_missed": 1, "dropped": 1, "not_attempted": 2}


def test_times_rates_errors_and_contacts():
    f = harvest_figures(outcomes(), RunTotals(field_time_s=1800.0, picking_time_s=60.0, arm_stem_contacts=1,
                                              arm_leaf_contacts=3, base_plant_contacts=2, route_time_s=1700.0,
                                              real_time_factor=1.1))
    assert f["cycle_time_s"]["median"] == pytest.approx(6.0)         # 4, 5, 6, 7, 20
    assert f["cycle_time_s"]["p95"] == pytest.approx(17.4)           # numpy's linear interpolation
    assert f["bolls_per_hour"] == pytest.approx(10.0)                # 5 in half an hour
    assert f["bolls_per_hour_picking"] == pytest.approx(300.0)       # 5 in a minute of picking
    # the picked targets' errors only (the missed capture's 0.5 m is not a picked target)
    assert f["localization_error_m"]["median"] == pytest.approx(0.008)
    assert f["localization_error_m"]["p95"] == pytest.approx(0.026)
    assert (f["arm_stem_contacts"], f["arm_leaf_contacts"], f["base_plant_contacts"]) == (1, 3, 2)
    assert (f["route_time_s"], f["real_time_factor"]) == (1700.0, 1.1)


def test_empty_populations_give_none_not_made_up_figures():
    f = harvest_figures([BollOutcome(0), BollOutcome(1)], RunTotals(field_time_s=0.0))
    assert f["harvest_success_percent"] is None and f["field_harvest_percent"] == 0.0
    assert f["cycle_time_s"] == {"median": None, "p95": None} and f["bolls_per_hour"] is None
    assert f["localization_error_m"]["median"] is None and f["bolls_per_hour_picking"] is None
    assert harvest_figures([], {"field_time_s": 10.0})["open_bolls"] == 0


def test_bad_records_are_refused_with_the_reason():
    run = RunTotals(field_time_s=1.0)
    with pytest.raises(ValueError, match="unique"):
        harvest_figures([BollOutcome(1), BollOutcome(1)], run)
    with pytest.raises(ValueError, match="unknown field"):
        harvest_figures([{"boll_id": 1, "colour": "white"}], run)
    with pytest.raises(ValueError, match="in_bin needs picked"):
        BollOutcome(2, in_bin=True)
    with pytest.raises(ValueError, match="cycle_time_s"):
        BollOutcome(3, cycle_time_s=float("nan"))
    with pytest.raises(ValueError, match="field_time_s"):
        RunTotals(field_time_s=-1.0)
    with pytest.raises(ValueError, match="arm_stem_contacts"):
        RunTotals(field_time_s=1.0, arm_stem_contacts=-2)
    with pytest.raises(ValueError, match="mapping"):
        harvest_figures(["boll"], run)
