import pytest

from cottonsim_navigation.power.battery import BatteryConfig, BatteryModel


def test_drain_matches_power_budget():
    b = BatteryModel(BatteryConfig(initial_percentage=1.0))
    # at 0.5 m/s: 60 + 60 = 120 W; one hour drains 120 Wh / ~25 V ~ 4.8 Ah (~24 %)
    for _ in range(3600):
        r = b.step(1.0, 0.5, 0.0)
    v_mean = 0.5 * (25.46 + r.voltage)
    assert r.charge == pytest.approx(20.0 - 120.0 / v_mean, rel=0.02)
    assert r.current < 0 and r.capacity == 20.0 and 0.7 < r.percentage < 0.8
    assert 3.0 <= BatteryModel().hours_left(0.5, 0.0) <= 5.0


def test_low_start_and_monotone_voltage():
    b = BatteryModel(BatteryConfig(initial_percentage=0.41, drain_scale=50.0))
    v0 = b.reading().voltage
    steps = 0
    while b.percentage > 0.40:
        b.step(1.0, 0.5, 0.2)
        steps += 1
    assert 0 < steps < 200 and b.reading().voltage < v0
    with pytest.raises(ValueError, match="initial_percentage"):
        BatteryConfig(initial_percentage=1.5)
    with pytest.raises(ValueError, match="dt_s"):
        b.step(float("nan"))
