"""Husky battery model: 24 V, 20 Ah sealed lead-acid.

Why: the paper's robot returns Home when its battery falls to 40 %; the
simulator needs a battery that drains plausibly with use. The model is a
charge counter:

    P [W] = idle_power_w + motion_power_w_per_mps * |v| + turn_power_w_per_radps * |w|
    I [A] = P / V,     charge_ah -= I * dt / 3600

and the terminal voltage is a straight-line open-circuit curve of a 12-cell
lead-acid pack at rest (about 2.12 V per cell full, 1.93 V empty: 25.5 V ..
23.2 V) minus the drop over an internal resistance.

Defaults: 60 W idle (controller, sensors, computer) + 120 W per m/s + 30 W
per rad/s. At the original's 0.5 m/s cruise that is ~120 W, i.e. about 4 h
from a full 480 Wh pack (idle only: ~8 h; 1 m/s flat out: ~2.7 h), which
matches the Husky's stated 3-5 h of typical use. The numbers are plausible
choices, not measurements.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from cottonsim_common.validation import require_fields


@dataclass(frozen=True)
class BatteryConfig:
    """Battery parameters.

    design_capacity_ah [Ah]; initial_percentage (0..1] of it at start;
    idle_power_w [W]; motion_power_w_per_mps [W per m/s]; turn_power_w_per_radps
    [W per rad/s]; voltage_full_v / voltage_empty_v [V]: open-circuit voltage at
    100 % / 0 %; internal_resistance_ohm [ohm]; drain_scale: multiplies all
    power (to fast-forward drain in tests / short demos).
    """

    design_capacity_ah: float = 20.0
    initial_percentage: float = 1.0
    idle_power_w: float = 60.0
    motion_power_w_per_mps: float = 120.0
    turn_power_w_per_radps: float = 30.0
    voltage_full_v: float = 25.46
    voltage_empty_v: float = 23.16
    internal_resistance_ohm: float = 0.05
    drain_scale: float = 1.0

    def __post_init__(self) -> None:
        require_fields(self, positive=("design_capacity_ah",),
                       non_negative=("idle_power_w", "motion_power_w_per_mps", "turn_power_w_per_radps",
                                     "voltage_full_v", "voltage_empty_v", "internal_resistance_ohm", "drain_scale"),
                       fractions=("initial_percentage",))
        if not 0 < self.voltage_empty_v < self.voltage_full_v:
            raise ValueError("need 0 < voltage_empty_v < voltage_full_v")


@dataclass(frozen=True)
class BatteryReading:
    """The fields of sensor_msgs/BatteryState this model fills.

    voltage [V], current [A] (negative while discharging, as BatteryState
    defines it), charge / capacity / design_capacity [Ah], percentage 0..1.
    """

    voltage: float
    current: float
    charge: float
    capacity: float
    design_capacity: float
    percentage: float


class BatteryModel:
    """State of charge integrated over ``step(dt, v, w)`` calls."""

    def __init__(self, config: BatteryConfig = BatteryConfig()):
        self.config = config
        self.charge_ah = config.design_capacity_ah * config.initial_percentage
        self.current_a = 0.0
        self.elapsed_s = 0.0

    @property
    def percentage(self) -> float:
        return self.charge_ah / self.config.design_capacity_ah

    def power_w(self, v_mps: float, w_radps: float) -> float:
        c = self.config
        return c.drain_scale * (c.idle_power_w + c.motion_power_w_per_mps * abs(v_mps)
                                + c.turn_power_w_per_radps * abs(w_radps))

    def open_circuit_voltage(self) -> float:
        c = self.config
        return c.voltage_empty_v + (c.voltage_full_v - c.voltage_empty_v) * self.percentage

    def step(self, dt_s: float, v_mps: float = 0.0, w_radps: float = 0.0) -> BatteryReading:
        """Advance by dt_s seconds at linear speed v [m/s] and turn rate w [rad/s]."""
        for name, val in (("dt_s", dt_s), ("v_mps", v_mps), ("w_radps", w_radps)):
            if not math.isfinite(float(val)):
                raise ValueError(f"{name} must be finite, got {val!r}")
        if dt_s < 0:
            raise ValueError(f"dt_s must be >= 0, got {dt_s}")
        p = self.power_w(v_mps, w_radps)
        voltage = max(self.open_circuit_voltage(), 1e-3)
        current = p / voltage if self.charge_ah > 0 else 0.0
        self.charge_ah = max(0.0, self.charge_ah - current * dt_s / 3600.0)
        self.current_a = current
        self.elapsed_s += dt_s
        return self.reading()

    def reading(self) -> BatteryReading:
        c = self.config
        v = max(0.0, self.open_circuit_voltage() - self.current_a * c.internal_resistance_ohm)
        return BatteryReading(voltage=v, current=-self.current_a, charge=self.charge_ah,
                              capacity=c.design_capacity_ah, design_capacity=c.design_capacity_ah,
                              percentage=self.percentage)

    def hours_left(self, v_mps: float = 0.0, w_radps: float = 0.0) -> float:
        """Rough hours to empty at constant use (ignores the small voltage sag)."""
        p = self.power_w(v_mps, w_radps)
        if p <= 0:
            return math.inf
        return self.charge_ah * self.open_circuit_voltage() / p
