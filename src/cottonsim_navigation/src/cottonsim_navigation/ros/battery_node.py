"""battery: the Husky's battery as sensor_msgs/BatteryState, drained by the robot's motion.

The model is ``cottonsim_navigation.power.battery.BatteryModel``; this node
integrates it over sim time with the speed the odometry reports and publishes
the state at a fixed rate. The paper's return-home rule (40 %) belongs to the
navigator, which reads /battery/state.
"""
from __future__ import annotations

import dataclasses
import math
import threading
from typing import Optional

import rospy
from nav_msgs.msg import Odometry
from sensor_msgs.msg import BatteryState

from cottonsim_common.ros.conversions import finite_or_none
from cottonsim_common.ros.params import config_from_params, typed_param
from cottonsim_navigation.power.battery import BatteryConfig, BatteryModel, BatteryReading

# Odometry older than this [s of sim time] counts as "robot at rest".
_STALE_ODOMETRY_S = 1.0


def battery_state_msg(reading: BatteryReading, stamp: rospy.Time, frame_id: str) -> BatteryState:
    msg = BatteryState()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.voltage = float(reading.voltage)
    msg.current = float(reading.current)
    msg.charge = float(reading.charge)
    msg.capacity = float(reading.capacity)
    msg.design_capacity = float(reading.design_capacity)
    msg.percentage = float(reading.percentage)
    msg.temperature = float("nan")                      # not modelled (BatteryState: NaN = unmeasured)
    if reading.percentage <= 0.0:
        msg.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_NOT_CHARGING
        msg.power_supply_health = BatteryState.POWER_SUPPLY_HEALTH_DEAD
    else:
        msg.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        msg.power_supply_health = BatteryState.POWER_SUPPLY_HEALTH_GOOD
    msg.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_UNKNOWN   # sealed lead-acid: no constant
    msg.present = True
    msg.location = "husky"
    return msg


class BatteryNode:
    """Integrates the battery model over sim time and publishes its state.

    Subscriptions
      /odometry/filtered   nav_msgs/Odometry      body speed v [m/s] and turn rate w [rad/s]
                                                  (NaN messages ignored with a warning)
    Publications
      /battery/state       sensor_msgs/BatteryState  every 1/~rate s of sim time: voltage [V],
                                                  current [A] (< 0 discharging), charge / capacity [Ah],
                                                  percentage 0..1
    Parameters (private; config/battery.yaml, BatteryConfig)
      ~rate (float, 1.0): publishing rate [Hz]
      ~frame_id (str, base_link): header frame of the state
      ~design_capacity_ah (20), ~initial_percentage (1.0, 0..1), ~idle_power_w (60),
      ~motion_power_w_per_mps (120), ~turn_power_w_per_radps (30), ~voltage_full_v (25.46),
      ~voltage_empty_v (23.16), ~internal_resistance_ohm (0.05), ~drain_scale (1.0)
    ~drain_scale fast-forwards the drain: each sim second drains like drain_scale seconds, while
    current and voltage stay those of the real pack at that speed.
    The drain between two odometry messages uses the speed of the earlier one;
    without odometry for 1 s the robot counts as at rest (idle drain only).
    """

    def __init__(self):
        self.config = config_from_params(BatteryConfig)
        self.rate_hz = typed_param("~rate", 1.0)
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ValueError(f"parameter ~rate: must be > 0 [Hz], got {self.rate_hz}")
        self.frame_id = typed_param("~frame_id", "base_link")
        # drain_scale fast-forwards the charge counter (dt x scale) rather than scaling the power
        # in the model: the published current and voltage then stay those of the real pack.
        self.time_scale = self.config.drain_scale
        self.model = BatteryModel(dataclasses.replace(self.config, drain_scale=1.0))
        self._lock = threading.Lock()
        self._v = 0.0
        self._w = 0.0
        self._last_odom_s: Optional[float] = None
        self._last_step_s: Optional[float] = None
        self.pub = rospy.Publisher("/battery/state", BatteryState, queue_size=5)
        rospy.Subscriber("/odometry/filtered", Odometry, self._on_odom, queue_size=20)
        self.timer = rospy.Timer(rospy.Duration(1.0 / self.rate_hz), self._on_timer)

    def _advance(self, now_s: float) -> None:
        """Drain from the last step to now_s at the last known speed (call with the lock held)."""
        if self._last_step_s is None or now_s < self._last_step_s:
            self._last_step_s = now_s                         # first call, or the clock went back
            return
        v, w = self._v, self._w
        if self._last_odom_s is None or now_s - self._last_odom_s > _STALE_ODOMETRY_S:
            v = w = 0.0
        self.model.step((now_s - self._last_step_s) * self.time_scale, v, w)
        self._last_step_s = now_s

    def _on_odom(self, msg: Odometry):
        t = msg.twist.twist
        if not finite_or_none(t.linear.x, t.angular.z):
            rospy.logwarn_throttle(5.0, "battery: odometry with NaN speed ignored")
            return
        stamp_s = msg.header.stamp.to_sec()
        with self._lock:
            if self._last_step_s is not None and stamp_s >= self._last_step_s:
                self._advance(stamp_s)
            self._v, self._w = float(t.linear.x), float(t.angular.z)
            self._last_odom_s = stamp_s

    def _on_timer(self, _event):
        now = rospy.Time.now()
        with self._lock:
            self._advance(now.to_sec())
            reading = self.model.reading()
        self.pub.publish(battery_state_msg(reading, now, self.frame_id))
