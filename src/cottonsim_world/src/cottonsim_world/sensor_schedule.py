"""The simulator's timing of sensor work: periodic schedules, and readings held while a worker renders.

Used by ``Simulator`` (see its module docstring for the pipelined mode).
"""
from __future__ import annotations

import math
import time
from concurrent.futures import Future
from concurrent.futures import wait as futures_wait
from dataclasses import dataclass
from typing import Callable, Optional, Tuple


@dataclass
class Schedule:
    """A periodic task in sim time: due when now >= next_s."""

    name: str
    period_s: float
    next_s: float = 0.0
    active: bool = True
    wall_s: float = 0.0          # accumulated wall time of its updates [s]
    cpu_s: float = 0.0           # accumulated process CPU time of its updates, all threads [s]
    count: int = 0

    def due(self, now_s: float) -> bool:
        if now_s + 1e-9 < self.next_s:
            return False
        # Skip missed periods instead of bursting (a sensor fires once per step at most).
        self.next_s += self.period_s * max(1, math.floor((now_s - self.next_s) / self.period_s + 1e-9) + 1)
        return self.active


class HeldReading:
    """A place in the reading stream that ``step()`` has not returned yet (pipelined mode).

    Either a worker's job (``future``: (reading, wall [s], thread CPU [s]))
    or a reading made in the main thread that waits behind one.
    deadline_s: sim time [s] at which the physics waits for the job
    (its sensor's next due time, at most its stamp + the sensor's period); before_s: sim time [s] of the step
    before the stamp (every reading up to it precedes this one).
    """

    __slots__ = ("stamp_s", "before_s", "deadline_s", "schedule", "future", "reading")

    def __init__(self, stamp_s: float, before_s: float, deadline_s: float, schedule: Optional[Schedule],
                 future: Optional[Future], reading: object):
        self.stamp_s = stamp_s
        self.before_s = before_s
        self.deadline_s = deadline_s
        self.schedule = schedule
        self.future = future
        self.reading = reading


def timed_job(after: Optional[Future], produce: Callable[..., object], *args) -> Tuple[object, float, float]:
    """Run a sensor job on a worker: (reading, wall [s], CPU of this thread [s]).

    ``after``: the same sensor's previous job, which must finish first (its model and noise
    generator are not shared); with one worker the queue's order already ensures that.
    """
    if after is not None:
        futures_wait((after,))
    t0, c0 = time.perf_counter(), time.thread_time()
    reading = produce(*args)
    return reading, time.perf_counter() - t0, time.thread_time() - c0
