"""The farm's cotton bolls as objects with a state: on the plant, held by an end effector, in the bin.

Why: a harvest changes the field. The plant models hold every boll's
centre and radius (``farm.model.PlantModel``); ``BollField`` turns them into
numbered objects whose state the arm side changes (detach, carry, drop in
the bin) and which the sensors and the ground-truth topic follow: the
simulator hides a boll from the cameras and the LiDAR as soon as it leaves
its plant (``sensors.scene.SensorScene.set_hidden_bolls``).

Identity: boll ids are 0 .. count - 1, numbered over ``farm.plants`` in
order (ascending plant id) and, within a plant, in the order of its model's
``boll_centres`` (``index_on_plant``). The field is a pure function of the
farm, and the farm of its seed: the same seed and the same calls give the
same field (``revision`` counts the changes).

States and transitions (anything else raises ValueError naming the boll):

* ON_PLANT -> HELD      ``detach(boll_id, holder)``: an end effector takes it;
* HELD -> HELD          ``move_held(holder, position_m)``: it travels with the tool;
* HELD -> IN_BIN        ``drop_in_bin(boll_id)``: released over the bin;
* HELD -> DROPPED       ``drop(boll_id, position_m)``: let go away from the bin;
* ON_PLANT -> IN_BIN    ``drop_in_bin(boll_id)`` too: a vacuum tube that carries
                        the boll straight to the bin.

Positions are in the world frame [m] (z up, ground at z = 0); a held boll
is where ``move_held`` last put it, a binned one where it was released.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from cottonsim_common.validation import require_instance
from cottonsim_world.farm.model import Farm


class BollState(enum.IntEnum):
    """Where a boll is. The values are those of cottonsim_msgs/Boll's state constants."""

    ON_PLANT = 0
    HELD = 1
    IN_BIN = 2
    DROPPED = 3


@dataclass(frozen=True)
class BollFieldConfig:
    """Rules of the boll field.

    max_held_per_holder: how many bolls one holder (an end effector) may
        hold at once (>= 1; a vacuum nozzle holds one).
    """

    max_held_per_holder: int = 1

    def __post_init__(self) -> None:
        v = self.max_held_per_holder
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"BollFieldConfig.max_held_per_holder must be an integer >= 1, got {v!r}")


@dataclass(frozen=True)
class Boll:
    """One boll as the field holds it now (a copy: changing the field does not change it)."""

    boll_id: int
    plant_id: int
    index_on_plant: int                      # its index in the plant model's boll_centres
    position_m: Tuple[float, float, float]   # world frame [m]
    diameter_m: float
    state: BollState
    holder: str                              # "" unless HELD


def _check_point(name: str, point: Sequence[float]) -> np.ndarray:
    p = np.asarray(point, dtype=float).reshape(-1)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"{name} must be 3 finite coordinates [m], got {point!r}")
    return p


class BollField:
    """Every boll of a farm with its state (see the module docstring).

    Fixed per boll (arrays over ids, read-only): ``diameter_m``, ``plant_id``,
    ``index_on_plant`` and ``outward`` (count, 3), the horizontal unit vector
    from its plant's stem towards where it hung (the side an end effector
    approaches it from).
    """

    def __init__(self, farm: Farm, config: BollFieldConfig = BollFieldConfig()) -> None:
        require_instance("config", config, BollFieldConfig)
        if not hasattr(farm, "plants"):
            raise ValueError("farm must be a farm.model.Farm (it has no 'plants')")
        self.config = config
        centres, diameters, plant_ids, index_on_plant, stems = [], [], [], [], []
        for plant in farm.plants:
            c = plant.boll_centres_world().reshape(-1, 3)
            r = np.asarray(plant.model.boll_radii, dtype=float).reshape(-1)
            if len(c) != len(r):
                raise ValueError(f"plant {plant.plant_id}: {len(c)} boll centres but {len(r)} radii")
            centres.append(c)
            diameters.append(2.0 * r)
            plant_ids.append(np.full(len(r), plant.plant_id, dtype=np.int64))
            index_on_plant.append(np.arange(len(r), dtype=np.int64))
            stems.append(np.tile([plant.x_m, plant.y_m], (len(r), 1)))
        self._origin_m = np.concatenate(centres) if centres else np.zeros((0, 3))
        self._origin_m.setflags(write=False)
        self.diameter_m = np.concatenate(diameters) if diameters else np.zeros(0)
        self.plant_id = np.concatenate(plant_ids) if plant_ids else np.zeros(0, np.int64)
        self.index_on_plant = np.concatenate(index_on_plant) if index_on_plant else np.zeros(0, np.int64)
        # where each boll faces on its plant: horizontally away from the stem (+x for a boll on the stem)
        away = self._origin_m[:, :2] - (np.concatenate(stems) if stems else np.zeros((0, 2)))
        norm = np.linalg.norm(away, axis=1, keepdims=True)
        self.outward = np.zeros((len(away), 3))
        self.outward[:, :2] = np.where(norm > 1e-9, away / np.maximum(norm, 1e-300), [1.0, 0.0])
        for a in (self.diameter_m, self.plant_id, self.index_on_plant, self.outward):
            a.setflags(write=False)
        self._position_m = self._origin_m.copy()
        self._state = np.zeros(len(self._origin_m), dtype=np.uint8)
        self._holder: Dict[int, str] = {}
        self.revision = 0

    # ------------------------------------------------------------------ queries
    @property
    def count(self) -> int:
        return int(len(self._state))

    def _check_id(self, boll_id: int) -> int:
        if isinstance(boll_id, bool) or not isinstance(boll_id, (int, np.integer)):
            raise ValueError(f"boll id must be an integer, got {boll_id!r}")
        if not 0 <= int(boll_id) < self.count:
            raise ValueError(f"unknown boll id {boll_id} (the field has ids 0..{self.count - 1})")
        return int(boll_id)

    def get(self, boll_id: int) -> Boll:
        """The boll with this id (ValueError for an unknown id)."""
        i = self._check_id(boll_id)
        return Boll(i, int(self.plant_id[i]), int(self.index_on_plant[i]), tuple(float(v) for v in self._position_m[i]),
                    float(self.diameter_m[i]), BollState(int(self._state[i])), self._holder.get(i, ""))

    def all(self) -> List[Boll]:
        """Every boll, in id order."""
        return [self.get(i) for i in range(self.count)]

    def positions_m(self) -> np.ndarray:
        """(count, 3) world positions now [m] (a copy)."""
        return self._position_m.copy()

    def states(self) -> np.ndarray:
        """(count,) uint8 BollState values (a copy)."""
        return self._state.copy()

    def off_plant_mask(self) -> np.ndarray:
        """(count,) bool: the bolls that have left their plant (what the sensors must not see)."""
        return self._state != BollState.ON_PLANT

    def held_by(self, holder: str) -> List[int]:
        """Ids of the bolls ``holder`` holds, ascending."""
        return sorted(i for i, h in self._holder.items() if h == holder)

    def nearest(self, point_m: Sequence[float], state: Optional[BollState] = BollState.ON_PLANT,
                max_distance_m: float = math.inf) -> Optional[Boll]:
        """The boll (in ``state``; None = any) whose centre is nearest to ``point_m`` (world [m]), or None
        when none lies within ``max_distance_m``. Ties go to the lower id."""
        ids = self.within(point_m, max_distance_m, state)
        return self.get(ids[0]) if ids else None

    def within(self, point_m: Sequence[float], radius_m: float,
               state: Optional[BollState] = BollState.ON_PLANT) -> List[int]:
        """Ids of the bolls (in ``state``; None = any) with their centre within ``radius_m`` of
        ``point_m`` (world [m]), nearest first (ties: lower id first)."""
        p = _check_point("point_m", point_m)
        if not (radius_m >= 0.0):
            raise ValueError(f"radius_m must be >= 0 (inf allowed), got {radius_m!r}")
        d = np.linalg.norm(self._position_m - p, axis=1)
        keep = d <= radius_m
        if state is not None:
            keep &= self._state == BollState(state)
        ids = np.nonzero(keep)[0]
        return [int(i) for i in ids[np.argsort(d[ids], kind="stable")]]

    # ------------------------------------------------------------------ changes
    def detach(self, boll_id: int, holder: str, position_m: Optional[Sequence[float]] = None) -> Boll:
        """An end effector ``holder`` takes a boll off its plant (ON_PLANT -> HELD).

        position_m: where the held boll is now (world [m]); default: where it hung.
        """
        i = self._check_id(boll_id)
        if not isinstance(holder, str) or not holder.strip():
            raise ValueError(f"holder must be a non-empty name, got {holder!r}")
        if self._state[i] != BollState.ON_PLANT:
            raise ValueError(f"boll {i} cannot be detached: it is {BollState(int(self._state[i])).name}, "
                             f"not ON_PLANT")
        held = self.held_by(holder)
        if len(held) >= self.config.max_held_per_holder:
            raise ValueError(f"holder {holder!r} already holds {len(held)} boll(s) {held} "
                             f"(max_held_per_holder = {self.config.max_held_per_holder})")
        p = self._position_m[i] if position_m is None else _check_point("position_m", position_m)
        self._state[i] = BollState.HELD
        self._holder[i] = holder
        self._position_m[i] = p
        self.revision += 1
        return self.get(i)

    def move_held(self, holder: str, position_m: Sequence[float]) -> List[int]:
        """Put every boll ``holder`` holds at ``position_m`` (world [m], e.g. the nozzle tip); returns their ids."""
        p = _check_point("position_m", position_m)
        ids = self.held_by(holder)
        moved = [i for i in ids if not np.array_equal(self._position_m[i], p)]
        for i in moved:
            self._position_m[i] = p
        if moved:
            self.revision += 1
        return ids

    def drop_in_bin(self, boll_id: int, position_m: Optional[Sequence[float]] = None) -> Boll:
        """A boll reaches the bin (HELD or ON_PLANT -> IN_BIN); position_m: where (default: where it is)."""
        i = self._check_id(boll_id)
        if self._state[i] == BollState.IN_BIN:
            raise ValueError(f"boll {i} is already IN_BIN")
        if position_m is not None:
            self._position_m[i] = _check_point("position_m", position_m)
        self._state[i] = BollState.IN_BIN
        self._holder.pop(i, None)
        self.revision += 1
        return self.get(i)

    def drop(self, boll_id: int, position_m: Sequence[float]) -> Boll:
        """A held boll is let go away from the bin (HELD -> DROPPED): it lies at ``position_m`` (world [m])."""
        i = self._check_id(boll_id)
        if self._state[i] != BollState.HELD:
            raise ValueError(f"boll {i} cannot be dropped: it is {BollState(int(self._state[i])).name}, not HELD")
        self._position_m[i] = _check_point("position_m", position_m)
        self._state[i] = BollState.DROPPED
        self._holder.pop(i, None)
        self.revision += 1
        return self.get(i)

    def set_state(self, boll_id: int, state: BollState, holder: str = "",
                  position_m: Optional[Sequence[float]] = None) -> Boll:
        """One transition by the target state (what /sim/set_boll_state asks): HELD = ``detach``
        (or ``move_held`` of a boll ``holder`` already holds), IN_BIN = ``drop_in_bin``. A boll never
        goes back on its plant: ON_PLANT is accepted only for a boll that is still there."""
        i = self._check_id(boll_id)
        try:
            target = BollState(int(state))
        except ValueError:
            raise ValueError(f"unknown boll state {state!r} (0 ON_PLANT, 1 HELD, 2 IN_BIN, 3 DROPPED)") from None
        now = BollState(int(self._state[i]))
        if target == BollState.ON_PLANT:
            if now != BollState.ON_PLANT:
                raise ValueError(f"boll {i} is {now.name}; a boll cannot go back on its plant")
            return self.get(i)
        if target == BollState.HELD:
            if now == BollState.HELD:
                if holder and holder != self._holder[i]:
                    raise ValueError(f"boll {i} is held by {self._holder[i]!r}, not {holder!r}")
                if position_m is not None:
                    self.move_held(self._holder[i], position_m)
                return self.get(i)
            return self.detach(i, holder, position_m)
        if target == BollState.DROPPED:
            return self.drop(i, self._position_m[i] if position_m is None else position_m)
        return self.drop_in_bin(i, position_m)
