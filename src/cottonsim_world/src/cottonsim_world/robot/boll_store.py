"""Where the vacuum nozzle finds bolls and what it does to them: the ``BollStore`` interface.

The nozzle (robot/vacuum.py) needs five things of the world's bolls, all in
the world frame [m]:

* ``nearest_open(point)``: the open boll (on its plant) whose centre is
  nearest the point, as a ``BollView`` (id, centre, outward direction from
  the stem, radius), or None when no boll is open;
* ``attach(id)``: the boll leaves its plant and is held by the end effector;
* ``carry(id, centre)``: the held boll's centre now (it travels with the tool);
* ``release_into_bin(id)``: the held boll is in the robot's bin;
* ``drop(id, centre)``: the held boll is let go away from the bin (it falls
  where it is; it is neither on the plant nor in the bin).

``BollFieldStore`` is the simulator's: it acts on the world's ``BollField``
(farm/bolls.py), so a captured boll leaves the cameras, the LiDAR and the
ground truth at once; the field refuses transitions that make no sense
(attach a boll that is not open, release one that is not held) with a
ValueError naming the boll.
"""
from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

OPEN, HELD, IN_BIN, DROPPED = "open", "held", "in_bin", "dropped"


@dataclass(frozen=True)
class BollView:
    """One boll as the nozzle sees it: id, centre [m] and unit outward direction (world), radius [m]."""

    boll_id: int
    centre_m: np.ndarray
    outward: np.ndarray
    radius_m: float


class BollStore(abc.ABC):
    """The bolls' states as the vacuum nozzle changes them (see the module docstring)."""

    @abc.abstractmethod
    def nearest_open(self, point_m: Sequence[float]) -> Optional[BollView]:
        ...

    @abc.abstractmethod
    def attach(self, boll_id: int) -> None:
        ...

    @abc.abstractmethod
    def carry(self, boll_id: int, centre_m: Sequence[float]) -> None:
        ...

    @abc.abstractmethod
    def release_into_bin(self, boll_id: int) -> None:
        ...

    @abc.abstractmethod
    def drop(self, boll_id: int, centre_m: Sequence[float]) -> None:
        ...


class BollFieldStore(BollStore):
    """The nozzle's view of the world's ``BollField``: one holder name for the end effector."""

    _STATE_NAMES = {0: OPEN, 1: HELD, 2: IN_BIN, 3: DROPPED}

    def __init__(self, field, holder: str = "ur5e_vacuum_nozzle"):
        self.field = field
        self.holder = holder

    @classmethod
    def of_plants(cls, plants: Sequence, holder: str = "ur5e_vacuum_nozzle") -> "BollFieldStore":
        """The store of a boll field made of these plants alone (a hand-built scene, a benchmark)."""
        from cottonsim_common.pose import Pose2D
        from cottonsim_world.farm.bolls import BollField
        from cottonsim_world.farm.model import Farm
        return cls(BollField(Farm(None, list(plants), [], Pose2D(0.0, 0.0, 0.0))), holder)

    def __len__(self) -> int:
        return self.field.count

    def state(self, boll_id: int) -> str:
        return self._STATE_NAMES[int(self.field.get(boll_id).state)]

    def nearest_open(self, point_m: Sequence[float]) -> Optional[BollView]:
        boll = self.field.nearest(point_m)
        if boll is None:
            return None
        i = boll.boll_id
        return BollView(i, np.array(boll.position_m), self.field.outward[i].copy(), 0.5 * boll.diameter_m)

    def attach(self, boll_id: int) -> None:
        self.field.detach(boll_id, self.holder)

    def carry(self, boll_id: int, centre_m: Sequence[float]) -> None:
        if boll_id not in self.field.held_by(self.holder):
            raise ValueError(f"boll {boll_id} is {self.state(boll_id)}, not held")
        self.field.move_held(self.holder, centre_m)

    def release_into_bin(self, boll_id: int) -> None:
        if boll_id not in self.field.held_by(self.holder):
            raise ValueError(f"boll {boll_id} is {self.state(boll_id)}, not held")
        self.field.drop_in_bin(boll_id)

    def drop(self, boll_id: int, centre_m: Sequence[float]) -> None:
        self.field.drop(boll_id, centre_m)
