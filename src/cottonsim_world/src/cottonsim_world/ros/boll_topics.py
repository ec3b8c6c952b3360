"""The bridge's boll ground truth: the latched /sim/bolls topic and the /sim/set_boll_state service.

``BollTopics`` belongs to ``SimBridgeNode`` (``ros/bridge_node.py``) and works
on its ``Simulator``'s ``bolls`` (``farm.bolls.BollField``):

Publication
  /sim/bolls             cottonsim_msgs/BollArray   latched, frame world: every boll (id, plant, position,
                                                    diameter, state, holder). Published at start and at
                                                    once when a boll changes state; a held boll's position
                                                    in it is where it was then (it moves on /sim/bolls/held)
  /sim/bolls/held        cottonsim_msgs/BollArray   latched, frame world: the held bolls only, while they
                                                    move with the tool, at most every ~bolls_min_period_s
                                                    of sim time (and once empty when none is held any more)

Why two topics: the field has thousands of bolls, and a full array at the carrying rate cost the
bridge more CPU than its physics and LiDAR together; a state change happens twice per pick.
Service
  /sim/set_boll_state    cottonsim_msgs/SetBollState  one boll's transition (``BollField.set_state``), done
                                                    by the simulation loop between two physics steps;
                                                    success false + message when refused
Parameter (private)
  ~bolls_min_period_s (float, 0.1): least sim time between two /sim/bolls/held messages [s] (a boll
                                    carried by the arm moves every arm step)

Code in the bridge's process (the arm's nozzle capture) changes ``sim.bolls``
directly from the simulation loop; ``update`` publishes what changed.
"""
from __future__ import annotations

import math
import threading
from typing import List, Optional, Sequence

import numpy as np
import rospy
from cottonsim_msgs.msg import Boll as BollMsg
from cottonsim_msgs.msg import BollArray
from cottonsim_msgs.srv import SetBollState, SetBollStateResponse
from geometry_msgs.msg import Point

from cottonsim_world.farm.bolls import Boll, BollField, BollState
from cottonsim_common.ros import conversions as conv

WAIT_FOR_LOOP_S = 10.0      # wall time a service call waits for the simulation loop


def boll_msg(boll: Boll) -> BollMsg:
    return BollMsg(id=boll.boll_id, plant_id=boll.plant_id, position=Point(*boll.position_m),
                   diameter_m=boll.diameter_m, state=int(boll.state), holder=boll.holder)


def boll_array_msg(field: BollField, stamp_s: float, frame_id: str = "world",
                   ids: Optional[Sequence[int]] = None) -> BollArray:
    """Every boll of the field, or those of ``ids``."""
    bolls = field.all() if ids is None else [field.get(int(i)) for i in ids]
    msg = BollArray(revision=field.revision, bolls=[boll_msg(b) for b in bolls])
    msg.header = conv.header(conv.to_time(stamp_s), frame_id)
    return msg


class BollTopics:
    """/sim/bolls and /sim/set_boll_state (module docstring). ``update(now_s)`` runs in the simulation loop."""

    def __init__(self, field: BollField) -> None:
        self.field = field
        self.min_period_s = float(rospy.get_param("~bolls_min_period_s", 0.1))
        if not (math.isfinite(self.min_period_s) and self.min_period_s >= 0.0):
            raise ValueError(f"~bolls_min_period_s must be a finite time >= 0 [s], got {self.min_period_s}")
        self.pub = rospy.Publisher("/sim/bolls", BollArray, queue_size=1, latch=True)
        self.held_pub = rospy.Publisher("/sim/bolls/held", BollArray, queue_size=1, latch=True)
        self._held_published = False            # the last /sim/bolls/held listed a boll
        self._lock = threading.Lock()
        self._pending: List[list] = []          # [request, Event, response], answered by the simulation loop
        self._published_revision: Optional[int] = None
        self._published_states: Optional[np.ndarray] = None
        self._published_s = -math.inf
        rospy.Service("/sim/set_boll_state", SetBollState, self._on_set_state)

    def _on_set_state(self, req) -> SetBollStateResponse:
        job = [req, threading.Event(), None]
        with self._lock:
            self._pending.append(job)
        if not job[1].wait(WAIT_FOR_LOOP_S):
            return SetBollStateResponse(success=False, message="the simulation loop did not take the request "
                                                               f"within {WAIT_FOR_LOOP_S:.0f} s (wall)")
        return job[2]

    def _apply(self, req) -> SetBollStateResponse:
        position = (req.position.x, req.position.y, req.position.z) if req.set_position else None
        try:
            boll = self.field.set_state(int(req.id), req.state, req.holder.strip(), position)
        except ValueError as exc:
            before = boll_msg(self.field.get(int(req.id))) if 0 <= req.id < self.field.count else BollMsg()
            return SetBollStateResponse(success=False, message=str(exc), boll=before)
        rospy.loginfo("sim_bridge: boll %d is %s%s", boll.boll_id, boll.state.name,
                      f" (held by {boll.holder})" if boll.holder else "")
        return SetBollStateResponse(success=True, message=f"boll {boll.boll_id} is {boll.state.name}",
                                    boll=boll_msg(boll))

    def update(self, now_s: float) -> None:
        """Answer the pending requests, then publish /sim/bolls if it is due (see the module docstring)."""
        with self._lock:
            jobs, self._pending = self._pending, []
        for job in jobs:
            job[2] = self._apply(job[0])
            job[1].set()
        field = self.field
        if field.revision == self._published_revision:
            return
        states = field.states()
        if self._published_states is None or not np.array_equal(states, self._published_states):
            self.pub.publish(boll_array_msg(field, now_s))
            self._published_states = states
        elif now_s - self._published_s < self.min_period_s:
            return
        held = np.flatnonzero(states == int(BollState.HELD))
        if len(held) or self._held_published:
            self.held_pub.publish(boll_array_msg(field, now_s, ids=held))
            self._held_published = bool(len(held))
        self._published_revision = field.revision
        self._published_s = now_s
