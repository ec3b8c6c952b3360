"""Sensor faults: GPS outages and degradation, multipath jumps, camera blackouts, LiDAR dropouts.

``schedule`` holds the validated fault descriptions (``FaultSpec``, ``FaultScheduleConfig``),
``injector`` applies them to the simulator's readings (``FaultInjector``).
"""
from cottonsim_world.faults.injector import FaultInjector
from cottonsim_world.faults.schedule import (FAULT_KINDS, GPS_STATUS_FIX, GPS_STATUS_GBAS_FIX, GPS_STATUS_NO_FIX,
                                             GPS_STATUS_SBAS_FIX, FaultScheduleConfig, FaultSpec,
                                             fault_from_mapping, fault_schedule_from_list)

__all__ = ["FAULT_KINDS", "GPS_STATUS_FIX", "GPS_STATUS_GBAS_FIX", "GPS_STATUS_NO_FIX", "GPS_STATUS_SBAS_FIX",
           "FaultInjector", "FaultScheduleConfig", "FaultSpec", "fault_from_mapping", "fault_schedule_from_list"]
