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
ground truth at once. ``FarmBollStore`` is a small in-memory implementation from the farm's ground
truth (``Plant.boll_centres_world``): ids are running numbers over the plants
in farm order, a boll's outward direction is horizontal, from its plant's
stem axis to its centre. It keeps each boll's state and position and
refuses transitions that make no sense (attach a boll that is not open,
release one that is not held) with a ValueError naming the boll.
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


class FarmBollStore(BollStore):
    """Bolls of a farm's plants, kept in memory (see the module docstring)."""

    def __init__(self, plants: Sequence):
        centres, outwards, radii, plant_ids = [], [], [], []
        for plant in plants:
            c = plant.boll_centres_world()
            if not len(c):
                continue
            out = c - np.array([plant.x_m, plant.y_m, 0.0])
            out[:, 2] = 0.0
            norm = np.linalg.norm(out, axis=1, keepdims=True)
            centres.append(c)
            outwards.append(np.where(norm > 1e-9, out / np.where(norm > 1e-9, norm, 1.0), 0.0))
            radii.append(np.asarray(plant.model.boll_radii, dtype=float))
            plant_ids.append(np.full(len(c), plant.plant_id))
        self.centres_m = np.concatenate(centres) if centres else np.zeros((0, 3))
        self.outwards = np.concatenate(outwards) if outwards else np.zeros((0, 3))
        self.radii_m = np.concatenate(radii) if radii else np.zeros(0)
        self.plant_ids = np.concatenate(plant_ids) if plant_ids else np.zeros(0, dtype=int)
        self.states = np.array([OPEN] * len(self.centres_m), dtype=object)
        self._open = np.ones(len(self.centres_m), dtype=bool)

    def __len__(self) -> int:
        return len(self.centres_m)

    def state(self, boll_id: int) -> str:
        self._check(boll_id)
        return str(self.states[boll_id])

    def _check(self, boll_id: int, expected: Optional[str] = None) -> None:
        if not (isinstance(boll_id, (int, np.integer)) and 0 <= boll_id < len(self.centres_m)):
            raise ValueError(f"no boll {boll_id!r} (the farm has {len(self.centres_m)})")
        if expected is not None and self.states[boll_id] != expected:
            raise ValueError(f"boll {boll_id} is {self.states[boll_id]}, not {expected}")

    def _set(self, boll_id: int, state: str) -> None:
        self.states[boll_id] = state
        self._open[boll_id] = state == OPEN

    def nearest_open(self, point_m: Sequence[float]) -> Optional[BollView]:
        p = np.asarray(point_m, dtype=float).reshape(3)
        candidates = np.flatnonzero(self._open)
        if not len(candidates):
            return None
        i = int(candidates[np.argmin(np.linalg.norm(self.centres_m[candidates] - p, axis=1))])
        return BollView(i, self.centres_m[i].copy(), self.outwards[i].copy(), float(self.radii_m[i]))

    def attach(self, boll_id: int) -> None:
        self._check(boll_id, OPEN)
        self._set(boll_id, HELD)

    def carry(self, boll_id: int, centre_m: Sequence[float]) -> None:
        self._check(boll_id, HELD)
        self.centres_m[boll_id] = np.asarray(centre_m, dtype=float).reshape(3)

    def release_into_bin(self, boll_id: int) -> None:
        self._check(boll_id, HELD)
        self._set(boll_id, IN_BIN)

    def drop(self, boll_id: int, centre_m: Sequence[float]) -> None:
        self.carry(boll_id, centre_m)          # (checks that it is held)
        self._set(boll_id, DROPPED)


class BollFieldStore(BollStore):
    """The nozzle's view of the world's ``BollField``: one holder name for the end effector."""

    _STATE_NAMES = {0: OPEN, 1: HELD, 2: IN_BIN, 3: DROPPED}

    def __init__(self, field, holder: str = "ur5e_vacuum_nozzle"):
        self.field = field
        self.holder = holder

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
