"""The harvest's field plot (harvest/field_plot.py): classes of the bolls and the PNG it writes."""
import pytest

from cottonsim_experiments.harvest.field_plot import outcome_class, plot_harvest_field
from cottonsim_experiments.harvest.metrics import BollOutcome
from cottonsim_world.farm.model import Lane


def test_each_boll_gets_its_class():
    picked = dict(reachable=True, detected=True, attempted=True, picked=True)
    assert outcome_class(BollOutcome(0, **picked, in_bin=True)) == "picked"
    assert outcome_class(BollOutcome(1, reachable=True, detected=True, attempted=True,
                                     reason="capture_missed")) == "missed: capture_missed"
    assert outcome_class(BollOutcome(2, reachable=True, detected=True)) == "missed: not attempted"
    assert outcome_class(BollOutcome(3, reachable=True)) == "missed: not detected"
    assert outcome_class(BollOutcome(4)) == "not reachable"


def test_the_plot_is_a_png_and_bad_input_is_refused(tmp_path):
    outcomes = [BollOutcome(0, reachable=True, detected=True, attempted=True, picked=True, in_bin=True,
                            position_m=(0.8, 1.0, 0.5)),
                BollOutcome(1, reachable=True, position_m=(0.8, 1.7, 0.4)),
                BollOutcome(2, position_m=(1.0, 1.7, 0.4))]
    out = plot_harvest_field(tmp_path / "field.png", outcomes, [(0.9, 1.0), (0.9, 1.7)],
                             lanes=[Lane(0, 0.0, 0.5, 2.2)])
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 5000
    with pytest.raises(ValueError, match="position_m"):
        plot_harvest_field(tmp_path / "x.png", [BollOutcome(5)], [(0.0, 0.0)])
    with pytest.raises(ValueError, match="region"):
        plot_harvest_field(tmp_path / "y.png", outcomes, [(0.9, 1.0)], region=(1.0, 0.0, 0.0, 1.0))
