"""The bridge's sensor faults over ROS: /sim/inject_fault, /sim/clear_faults and /sim/faults/active.

``FaultTopics`` belongs to ``SimBridgeNode`` (``ros/bridge_node.py``) and works
on its ``Simulator``'s ``faults`` (``faults.FaultSchedule``):

Publication
  /sim/faults/active     cottonsim_msgs/SensorFaults  latched: the sensor faults active now, republished
                                                      whenever one starts or ends
Services
  /sim/inject_fault      cottonsim_msgs/InjectFault   start a sensor fault now (sim time) for duration_s: kind,
                                                      target (camera), parameters (YAML mapping of the kind's
                                                      keys, config/sim.yaml 'faults'); success false + message
                                                      when refused (unknown kind or key, bad value, camera not
                                                      simulated)
  /sim/clear_faults      cottonsim_msgs/ClearFaults   end every fault, scheduled or injected

A request is validated in the service's thread and handed to the simulation
loop, which starts it at its sim time (``apply_requests``) between two physics
steps; the service waits for that.
"""
from __future__ import annotations

import dataclasses
import json
import threading
from typing import List, Optional, Tuple

import rospy
from cottonsim_msgs.msg import SensorFault, SensorFaults
from cottonsim_msgs.srv import ClearFaults, ClearFaultsResponse, InjectFault, InjectFaultResponse

from cottonsim_common.config.yaml_files import load_yaml_text
from cottonsim_common.ros import conversions as conv
from cottonsim_world.faults import FaultSpec, fault_from_mapping

WAIT_FOR_LOOP_S = 10.0      # wall time a service call waits for the simulation loop


class FaultTopics:
    """/sim/inject_fault, /sim/clear_faults, /sim/faults/active (module docstring); ``apply_requests`` and
    ``publish_active`` run in the simulation loop."""

    def __init__(self, sim) -> None:
        self.sim = sim
        self.pub = rospy.Publisher("/sim/faults/active", SensorFaults, queue_size=2, latch=True)
        self._lock = threading.Lock()
        self._pending: List[list] = []      # [FaultSpec or None (= clear), Event, answer], done by the sim loop
        self._published: Optional[Tuple] = None
        rospy.Service("/sim/inject_fault", InjectFault, self._on_inject_fault)
        rospy.Service("/sim/clear_faults", ClearFaults, self._on_clear_faults)

    def _on_inject_fault(self, req):
        """Validate the fault here; the simulation loop starts it at its sim time (waits for that)."""
        try:
            spec = fault_spec_from_request(req.kind, req.target, req.duration_s, req.parameters)
        except ValueError as exc:
            return InjectFaultResponse(False, str(exc))
        answer = self._hand_to_loop(spec)
        if answer is None:
            return InjectFaultResponse(False, f"the simulation loop did not take the fault within "
                                              f"{WAIT_FOR_LOOP_S:.0f} s (wall)")
        if isinstance(answer, str):
            return InjectFaultResponse(False, answer)
        rospy.logwarn("sim_bridge: fault injected: %s", answer.describe())
        return InjectFaultResponse(True, answer.describe())

    def _on_clear_faults(self, _req):
        answer = self._hand_to_loop(None)
        if answer is None:
            return ClearFaultsResponse(0, f"the simulation loop did not take the request within "
                                          f"{WAIT_FOR_LOOP_S:.0f} s (wall)")
        rospy.logwarn("sim_bridge: %d sensor fault(s) cleared", answer)
        return ClearFaultsResponse(answer, f"{answer} fault(s) ended")

    def _hand_to_loop(self, spec: Optional[FaultSpec]):
        job = [spec, threading.Event(), None]
        with self._lock:
            self._pending.append(job)
        return job[2] if job[1].wait(WAIT_FOR_LOOP_S) else None

    def apply_requests(self) -> None:
        """Start (at the simulator's time now) or clear what the services asked for since the last call."""
        with self._lock:
            jobs, self._pending = self._pending, []
        now = self.sim.time_s
        for job in jobs:
            spec = job[0]
            if spec is None:
                job[2] = self.sim.faults.clear(now)
            else:
                try:
                    spec = dataclasses.replace(spec, start_s=now)
                    self.sim.faults.add(spec)
                    job[2] = spec
                except ValueError as exc:
                    job[2] = str(exc)
            job[1].set()

    def publish_active(self, now_s: float) -> None:
        """/sim/faults/active when the set of active faults differs from the last one published."""
        active = self.sim.faults.active(now_s) if not self.sim.faults.idle else []
        key = tuple((f.kind, f.target, f.start_s, f.end_s) for f in active)
        if key == self._published:
            return
        self._published = key
        msg = SensorFaults(active=[SensorFault(kind=f.kind, target=f.target, start_s=f.start_s, end_s=f.end_s,
                                               parameters=json.dumps(f.parameters())) for f in active])
        msg.header.stamp = conv.to_time(now_s)
        self.pub.publish(msg)


def fault_spec_from_request(kind: str, target: str, duration_s: float, parameters: str) -> FaultSpec:
    """A FaultSpec (start_s 0, set by the caller) from /sim/inject_fault's fields; ValueError naming the problem."""
    try:
        params = load_yaml_text(parameters, source="parameters") if parameters.strip() else {}
    except ValueError as exc:
        raise ValueError(f"parameters must be a YAML mapping of the fault's keys: {exc}") from None
    if params is None:
        params = {}
    if not isinstance(params, dict):
        raise ValueError(f"parameters must be a YAML mapping of the fault's keys, got {parameters!r}")
    for key in ("kind", "start_s", "duration_s"):
        if key in params:
            raise ValueError(f"parameters must not set '{key}' (the request's own field, or now for start_s)")
    mapping = dict(params, kind=kind, start_s=0.0, duration_s=duration_s)
    target = target.strip()
    if kind == "camera_blackout":
        if target and "camera" in params and params["camera"] != target:
            raise ValueError(f"target {target!r} and parameters camera {params['camera']!r} disagree")
        if target:
            mapping["camera"] = target
    elif target and target != {"lidar_dropout": "lidar"}.get(kind, "gps"):
        raise ValueError(f"target {target!r} does not fit {kind} (leave it empty)")
    return fault_from_mapping(mapping, f"fault {kind!r}")
