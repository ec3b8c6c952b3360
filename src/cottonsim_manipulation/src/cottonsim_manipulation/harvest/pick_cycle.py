"""One stop's pick cycle as a pure state machine: halt, pick every target, resume the route.

Phases, per target in the given order:

    HALT -> [ APPROACH -> CAPTURE -> DELIVER -> RELEASE ] * targets -> ResumeRoute -> DONE
    (a missed capture: CAPTURE -> RETREAT -> the next target)

* HALT: the route is paused (command HaltRoute); waits for the robot to stop. The targets are either
  given at the start, or chosen once the robot stands (``targets`` a callable: ``select(q_current,
  now_s)`` -> the ordered targets), from where it stopped: a robot may roll on while it brakes.
* APPROACH: the target is planned (``plan_pick(target, q_current)``, e.g.
  planning.approach.plan_approach) and the transit to its pre-grasp is sent.
* CAPTURE: vacuum on, the approach along the boll's outward direction is sent;
  then the capture is waited for (CaptureConfirmed / CaptureMissed).
* DELIVER: the boll caught, the retreat and the move to ``bin_joints_rad`` (the nozzle over the bin)
  go out as one trajectory (the arm rests at the retreat's end for no time): a trajectory of its own
  cost a phase change, the controller's report and the loop's reaction, ~0.1 s a pick.
* RETREAT: after a miss, the retreat alone, with the vacuum off; then the next target.
* RELEASE: vacuum off, ``release_dwell_s`` for the boll to drop; the target is 'ok'.

The machine is driven by calls with the current time [s]: start(), on_event()
and tick(); each returns the commands to carry out. Planning takes time: with a ``clock`` (a function returning
the time now [s]) the phase deadlines after a plan count from the time the
plan was done, not from the call's time. Every phase has a timeout,
so the cycle ends even when no event ever arrives: a timed-out target is
reported 'timeout' (the trajectory cancelled, the vacuum off) and the next one
starts. A failed target's result carries a reason: 'unreachable', 'ik_failed',
'collision' (from the planner), 'aborted' (the controller failed the
trajectory), 'capture_missed', 'lost' (the target vanished before the
capture), 'timeout', 'cancelled' (cancel(): the trajectory stopped, the vacuum off). Cycle time per boll: from the stop (first target) or the
previous target's end to its release.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, List, Optional, Sequence, Tuple, Union

import numpy as np

from cottonsim_common.kinematics.ur5e import joint_vector
from cottonsim_manipulation.planning.trajectory import JointTrajectory, TrajectoryConfig, concatenate, plan_trajectory

REASONS = ("ok", "unreachable", "ik_failed", "collision", "aborted", "capture_missed", "lost", "timeout", "cancelled")
HALT, APPROACH, CAPTURE, RETREAT, DELIVER, RELEASE, DONE = (
    "halt", "approach", "capture", "retreat", "deliver", "release", "done")


@dataclass(frozen=True)
class PickCycleConfig:
    """Timeouts [s] of the phases (each counted from entering it), the bin pose and the release dwell.

    halt_timeout_s: the robot must report stopped within this time, else the stop is abandoned.
    motion_margin_s: a motion phase times out after its trajectory's duration plus this margin.
    capture_wait_s: after the approach ends, how long the capture confirmation may take.
    release_dwell_s: time with the vacuum off over the bin before the next target.
    bin_joints_rad: the arm's joints with the nozzle over the bin (6 values, within the UR5e limits);
        default: the tip 15 cm above the rim of the URDF's cotton_bin, pointing down, clear of the robot. At
        7.5 cm the straight joint moves to and from the bolls on the robot's right clipped the bin's walls: offline
        (harvest_pick_contacts, seed 0, lane 2 driven south) 52 -> 61 of 66 bolls planned from abeam."""

    halt_timeout_s: float = 5.0
    motion_margin_s: float = 2.0
    capture_wait_s: float = 0.5
    release_dwell_s: float = 0.3
    bin_joints_rad: Tuple[float, ...] = (1.9, -1.825, -1.085, -4.94, -1.57, 0.33)

    def __post_init__(self) -> None:
        for name in ("halt_timeout_s", "motion_margin_s", "capture_wait_s", "release_dwell_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0.0 < value <= 600.0):
                raise ValueError(f"PickCycleConfig.{name} must be in (0, 600] s, got {value!r}")
        try:
            q = joint_vector(self.bin_joints_rad, "bin joints")
        except ValueError as exc:
            raise ValueError(f"PickCycleConfig.bin_joints_rad: {exc}") from None
        limits = TrajectoryConfig()
        if np.any(q < np.asarray(limits.lower_limits_rad)) or np.any(q > np.asarray(limits.upper_limits_rad)):
            raise ValueError(f"PickCycleConfig.bin_joints_rad {q.tolist()} are outside the UR5e joint limits")


@dataclass(frozen=True)
class PickTarget:
    """A boll to pick: its id, centre [m] and outward direction (arm base frame)."""

    target_id: int
    position_m: Tuple[float, float, float]
    outward: Tuple[float, float, float]


@dataclass(frozen=True)
class _Signal:
    """A command or event without fields (equal to another of its own class only)."""


# Commands (outputs).
class HaltRoute(_Signal):
    """Pause the route (the paper's halt)."""


class ResumeRoute(_Signal):
    """Go on along the route."""


@dataclass(frozen=True)
class SendTrajectory:
    trajectory: JointTrajectory
    purpose: str                      # 'transit', 'approach', 'deliver' (retreat and on to the bin) or 'retreat'


class CancelTrajectory(_Signal):
    """Stop the trajectory in progress."""


@dataclass(frozen=True)
class SetVacuum:
    on: bool


# Events (inputs).
class RobotStopped(_Signal):
    """The base has come to rest."""


class TrajectoryDone(_Signal):
    """The trajectory sent last has ended at its goal."""


@dataclass(frozen=True)
class TrajectoryFailed:
    detail: str = ""


class CaptureConfirmed(_Signal):
    """The nozzle holds the boll."""


@dataclass(frozen=True)
class CaptureMissed:
    detail: str = ""


@dataclass(frozen=True)
class TargetLost:
    target_id: int


@dataclass(frozen=True)
class PickResult:
    """reason: one of REASONS; cycle_time_s: from the stop or the previous target's end to this one's end [s]."""

    target_id: int
    reason: str
    detail: str = ""
    cycle_time_s: float = 0.0

    @property
    def ok(self) -> bool:
        return self.reason == "ok"


PlanPick = Callable[[PickTarget, np.ndarray], object]   # -> an ApproachResult (reason, detail, plan)
SelectTargets = Callable[[np.ndarray, float], Sequence[PickTarget]]   # (joints, time [s]) -> the stop's targets


def _unique(targets: Sequence[PickTarget]) -> List[PickTarget]:
    ids = [t.target_id for t in targets]
    if len(set(ids)) != len(ids):
        raise ValueError(f"target ids must be unique, got {ids}")
    return list(targets)


@dataclass
class _Current:
    target: PickTarget
    plan: object = None
    captured: bool = False
    approach_done: bool = False
    failure: Optional[Tuple[str, str]] = None


class PickCycle:
    """The pick cycle of one stop. Use start(), then on_event() and tick() until done."""

    def __init__(self, targets: Union[Sequence[PickTarget], SelectTargets], q_current_rad, plan_pick: PlanPick,
                 config: PickCycleConfig = PickCycleConfig(), trajectory_config: TrajectoryConfig = TrajectoryConfig(),
                 clock: Optional[Callable[[], float]] = None):
        self.config = config
        self._clock = clock
        self.trajectory_config = trajectory_config
        self._select: Optional[SelectTargets] = targets if callable(targets) else None
        self._queue: List[PickTarget] = [] if callable(targets) else _unique(targets)
        self._lost: set = set()
        self._q = joint_vector(q_current_rad, "current joints")
        self._plan_pick = plan_pick
        self.results: List[PickResult] = []
        self.phase: Optional[str] = None
        self._deadline_s = math.inf
        self._mark_s = 0.0
        self._current: Optional[_Current] = None

    @property
    def done(self) -> bool:
        return self.phase == DONE

    @property
    def upcoming_targets(self) -> List[PickTarget]:
        """The targets after the current one, in their order (empty before the robot stands)."""
        return list(self._queue)

    @property
    def current_target_id(self) -> Optional[int]:
        """The id of the target being picked, None between targets."""
        return None if self._current is None else self._current.target.target_id

    def _check_time(self, now_s: float) -> None:
        if isinstance(now_s, bool) or not isinstance(now_s, (int, float)) or not math.isfinite(now_s):
            raise ValueError(f"the time must be a finite number of seconds, got {now_s!r}")

    def start(self, now_s: float) -> list:
        if self.phase is not None:
            raise RuntimeError("the pick cycle has already started")
        self._check_time(now_s)
        self._mark_s = now_s
        if not self._queue and self._select is None:
            return self._finish(now_s)
        self._enter(HALT, now_s, self.config.halt_timeout_s)
        return [HaltRoute()]

    def on_event(self, event, now_s: float) -> list:
        """Commands in answer to an event; events that do not fit the phase are ignored."""
        self._check_time(now_s)
        if isinstance(event, TargetLost):
            return self._on_lost(event.target_id, now_s)
        phase, cur = self.phase, self._current
        if phase == HALT and isinstance(event, RobotStopped):
            if self._select is not None:
                self._queue = _unique(self._select(self._q.copy(), now_s))
            return self._next_target(now_s)
        if phase in (APPROACH, CAPTURE, RETREAT, DELIVER) and isinstance(event, TrajectoryFailed):
            return self._fail(cur, "aborted", f"{phase} trajectory failed: {event.detail}", now_s, cancel=False)
        if phase == CAPTURE and isinstance(event, CaptureConfirmed):
            cur.captured = True
            return self._retreat(now_s) if cur.approach_done else []
        if phase == CAPTURE and isinstance(event, CaptureMissed):
            cur.failure = ("capture_missed", event.detail or "the nozzle reached the boll without capturing it")
            return [SetVacuum(False)] + (self._retreat(now_s) if cur.approach_done else [])
        if not isinstance(event, TrajectoryDone):
            return []
        if phase == APPROACH:
            self._q = cur.plan.q_pregrasp_rad.copy()
            self._enter(CAPTURE, now_s, cur.plan.approach.duration_s + self.config.motion_margin_s)
            return [SetVacuum(True), SendTrajectory(cur.plan.approach, "approach")]
        if phase == CAPTURE:
            self._q = cur.plan.q_grasp_rad.copy()
            cur.approach_done = True
            if cur.captured or cur.failure:
                return self._retreat(now_s)
            self._enter(CAPTURE, now_s, self.config.capture_wait_s)
            return []
        if phase == RETREAT:
            self._q = cur.plan.q_retreat_rad.copy()
            return self._record(cur.failure[0], cur.failure[1], now_s) + self._next_target(now_s)
        if phase == DELIVER:
            self._q = np.asarray(self.config.bin_joints_rad, dtype=float)
            self._enter(RELEASE, now_s, self.config.release_dwell_s)
            return [SetVacuum(False)]
        return []

    def tick(self, now_s: float) -> list:
        """Commands when the phase's time is up (the release dwell ends, or a timeout)."""
        self._check_time(now_s)
        if self.phase in (None, DONE) or now_s < self._deadline_s:
            return []
        if self.phase == RELEASE:
            return self._record("ok", "in the bin", now_s) + self._next_target(now_s)
        if self.phase == HALT:
            for target in self._queue:
                self.results.append(PickResult(target.target_id, "timeout", "the robot did not stop", 0.0))
            self._queue = []
            return self._finish(now_s)
        if self.phase == CAPTURE and self._current.approach_done and not self._current.failure:
            self._current.failure = ("capture_missed", "no capture confirmed in time")
            return [SetVacuum(False)] + self._retreat(now_s)
        return self._fail(self._current, "timeout", f"{self.phase} took too long", now_s, cancel=True)

    # -- internals --------------------------------------------------------------------------------
    def _enter(self, phase: str, now_s: float, timeout_s: float) -> None:
        self.phase = phase
        self._deadline_s = now_s + timeout_s

    def _next_target(self, now_s: float) -> list:
        while self._queue:
            target = self._queue.pop(0)
            if target.target_id in self._lost:
                self.results.append(PickResult(target.target_id, "lost", "lost before its turn", 0.0))
                continue
            result = self._plan_pick(target, self._q.copy())
            if self._clock is not None:
                now_s = max(now_s, float(self._clock()))
            if not result.ok:
                self._current = _Current(target)
                self._record(result.reason, result.detail, now_s)
                continue
            self._current = _Current(target, result.plan)
            self._enter(APPROACH, now_s, result.plan.transit.duration_s + self.config.motion_margin_s)
            return [SendTrajectory(result.plan.transit, "transit")]
        return self._finish(now_s)

    def _retreat(self, now_s: float) -> list:
        """Back out of the plant: straight on to the bin with a caught boll (DELIVER), else alone (RETREAT)."""
        cur = self._current
        if cur.failure is None:
            to_bin = plan_trajectory(np.stack([cur.plan.q_retreat_rad, np.asarray(self.config.bin_joints_rad)]),
                                     self.trajectory_config)
            deliver = concatenate([cur.plan.retreat, to_bin])
            self._enter(DELIVER, now_s, deliver.duration_s + self.config.motion_margin_s)
            return [SendTrajectory(deliver, "deliver")]
        self._enter(RETREAT, now_s, cur.plan.retreat.duration_s + self.config.motion_margin_s)
        return [SendTrajectory(cur.plan.retreat, "retreat")]

    def _record(self, reason: str, detail: str, now_s: float) -> list:
        self.results.append(PickResult(self._current.target.target_id, reason, detail, now_s - self._mark_s))
        self._mark_s = now_s
        self._current = None
        return []

    def _fail(self, cur: _Current, reason: str, detail: str, now_s: float, cancel: bool) -> list:
        commands = [CancelTrajectory()] if cancel and self.phase != RELEASE else []
        commands.append(SetVacuum(False))
        self._record(reason, detail, now_s)
        # The arm stopped somewhere on its path: plan the next pick from there (the
        # last known stop; the ROS layer reports the real joints with update_joints).
        return commands + self._next_target(now_s)

    def cancel(self, now_s: float, detail: str = "cancelled") -> list:
        """End the cycle now: the current and every queued target 'cancelled' (the arm stops, the vacuum goes
        off, the route resumes). Nothing happens once the cycle is done."""
        self._check_time(now_s)
        if self.phase in (None, DONE):
            return []
        commands = [CancelTrajectory()] if self.phase in (APPROACH, CAPTURE, RETREAT, DELIVER) else []
        commands.append(SetVacuum(False))
        if self._current is not None:
            self._record("cancelled", detail, now_s)
        self.results.extend(PickResult(t.target_id, "cancelled", detail, 0.0) for t in self._queue)
        self._queue = []
        return commands + self._finish(now_s)

    def update_joints(self, q_rad) -> None:
        """The arm's measured joints (the next plan starts from them)."""
        self._q = joint_vector(q_rad, "joints")

    def _on_lost(self, target_id: int, now_s: float) -> list:
        cur = self._current
        if cur is not None and cur.target.target_id == target_id:
            if self.phase == APPROACH or (self.phase == CAPTURE and not cur.captured and not cur.approach_done):
                return self._fail(cur, "lost", "the target vanished before the capture", now_s, cancel=True)
            return []                    # captured or being captured: out of view because it is in the nozzle
        self._lost.add(target_id)
        return []

    def _finish(self, now_s: float) -> list:
        self._deadline_s = math.inf
        self.phase = DONE                # RESUME is the command itself: the stop is over
        return [ResumeRoute()]
