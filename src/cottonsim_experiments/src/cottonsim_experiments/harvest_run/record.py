"""What the harvest recorder keeps of a run (harvest.json): the harvest node's status and targets, the bolls' truth.

``HarvestRecord`` is fed the harvest node's /harvest/status (JSON text), its /harvest/targets (already
plain dicts, with each target's position in the world frame where the recorder knew the frame's pose)
and the simulator's /sim/bolls (plain dicts). It keeps the first boll message as the start and the
newest as the end, the newest status and targets, and which target each cycle time of the status
belongs to: the status's ``cycle_times_s`` lists the binned targets' cycle times in the order they were
binned, which is the order in which the targets turn 'picked' by a pick (last result 'ok'; the node may mark
a duplicate of a binned boll picked without a pick), within one targets message by id. A target's
world position is frozen once it is picked or abandoned (the estimate the pick used, in the world
frame of that moment). ``to_dict`` is harvest.json's content; ``write_json_atomic`` writes it so that a
reader never sees half a file.

harvest.json: {"version": 1, "status": {...} | null, "status_stamp_s", "targets_frame", "targets_stamp_s",
"targets": [{"id", "position": [x, y, z] (targets_frame), "position_world": [x, y, z] | null, "sigma_m",
"observations", "state", "attempts", "last_result", "first_seen_s", "last_seen_s"}], "picked_order": [ids], "cycle_time_by_target_s": {id: s},
"bolls_start": {"stamp_s", "bolls": [{"id", "plant", "position", "state"}]} | null, "bolls_end": same,
"status_changes": n}
"""
from __future__ import annotations

import json
import math
import os
import tempfile
from typing import Dict, List, Mapping, Optional, Sequence

VERSION = 1
TARGET_STATES = ("tentative", "confirmed", "picked", "abandoned")       # BollTarget's constants, in order
BOLL_STATES = ("on_plant", "held", "in_bin", "dropped")                  # Boll's constants, in order
_FINAL_TARGET_STATES = ("picked", "abandoned")


def _finite_point(value, what: str) -> List[float]:
    point = [float(v) for v in value]
    if len(point) != 3 or not all(math.isfinite(v) for v in point):
        raise ValueError(f"{what} must be three finite numbers, got {value!r}")
    return point


def _optional_stamp(value) -> Optional[float]:
    return None if value is None else float(value)


def state_name(value, names: Sequence[str], what: str) -> str:
    """A message's state constant (or its name) as its name."""
    if isinstance(value, str) and value in names:
        return value
    if not isinstance(value, bool) and isinstance(value, int) and 0 <= value < len(names):
        return names[value]
    raise ValueError(f"{what} must be one of {list(names)} or its index, got {value!r}")


class HarvestRecord:
    """The harvest run's record (module docstring); every ``on_*`` returns True when something changed."""

    def __init__(self) -> None:
        self.status: Optional[dict] = None
        self.status_stamp_s: Optional[float] = None
        self.status_changes = 0
        self.targets: Dict[int, dict] = {}
        self.targets_frame = ""
        self.targets_stamp_s: Optional[float] = None
        self.picked_order: List[int] = []
        self.bolls_start: Optional[dict] = None
        self.bolls_end: Optional[dict] = None

    def on_status(self, text: str, stamp_s: float) -> bool:
        """The node's /harvest/status JSON text; a text that is not a JSON object raises ValueError."""
        try:
            status = json.loads(text)
        except ValueError as exc:
            raise ValueError(f"/harvest/status is not JSON: {exc}") from None
        if not isinstance(status, dict):
            raise ValueError(f"/harvest/status must be a JSON object, got {type(status).__name__}")
        changed = {k: v for k, v in status.items() if k != "stamp_s"} != \
            {k: v for k, v in (self.status or {}).items() if k != "stamp_s"}
        self.status, self.status_stamp_s = status, float(stamp_s)
        if changed:
            self.status_changes += 1
        return changed

    def on_targets(self, frame: str, stamp_s: float, targets: Sequence[Mapping]) -> bool:
        """The node's targets: dicts with id, position, sigma_m, observations, state, attempts, last_result,
        first_seen_s and last_seen_s (the stamps of its first and newest detections [s]; None where not sent) and
        position_world (or None where the frame's pose in the world was not known)."""
        changed = False
        for t in sorted(targets, key=lambda t: int(t["id"])):
            tid = int(t["id"])
            entry = {"id": tid, "position": _finite_point(t["position"], f"target {tid} position"),
                     "sigma_m": float(t.get("sigma_m", 0.0)), "observations": int(t.get("observations", 0)),
                     "state": state_name(t["state"], TARGET_STATES, f"target {tid} state"),
                     "attempts": int(t.get("attempts", 0)), "last_result": str(t.get("last_result", "")),
                     "first_seen_s": _optional_stamp(t.get("first_seen_s")),
                     "last_seen_s": _optional_stamp(t.get("last_seen_s"))}
            world = t.get("position_world")
            entry["position_world"] = None if world is None else _finite_point(world, f"target {tid} position_world")
            old = self.targets.get(tid)
            if old is not None and old["state"] in _FINAL_TARGET_STATES and old["position_world"] is not None:
                entry["position_world"] = old["position_world"]
            if entry["state"] == "picked" and entry["last_result"] == "ok" and tid not in self.picked_order:
                self.picked_order.append(tid)
            if old != entry:
                self.targets[tid] = entry
                changed = True
        self.targets_frame, self.targets_stamp_s = str(frame), float(stamp_s)
        return changed

    def on_bolls(self, stamp_s: float, bolls: Sequence[Mapping]) -> bool:
        """Every boll of the field (id, plant, position, state): the first call is the start, each the end."""
        snapshot = {"stamp_s": float(stamp_s),
                    "bolls": [{"id": int(b["id"]), "plant": int(b["plant"]),
                               "position": _finite_point(b["position"], f"boll {b['id']} position"),
                               "state": state_name(b["state"], BOLL_STATES, f"boll {b['id']} state")}
                              for b in bolls]}
        if self.bolls_start is None:
            self.bolls_start = snapshot
        changed = self.bolls_end is None or [(b["id"], b["state"]) for b in self.bolls_end["bolls"]] != \
            [(b["id"], b["state"]) for b in snapshot["bolls"]]
        self.bolls_end = snapshot
        return changed

    def cycle_time_by_target(self) -> Dict[str, float]:
        """Target id (text) -> its cycle time [s]: the status's cycle times in the order the targets were picked."""
        times = list((self.status or {}).get("cycle_times_s") or [])
        return {str(tid): float(t) for tid, t in zip(self.picked_order, times)}

    def to_dict(self) -> dict:
        """harvest.json's content (module docstring)."""
        return {"version": VERSION, "status": self.status, "status_stamp_s": self.status_stamp_s,
                "targets_frame": self.targets_frame, "targets_stamp_s": self.targets_stamp_s,
                "targets": [self.targets[k] for k in sorted(self.targets)],
                "picked_order": list(self.picked_order),
                "cycle_time_by_target_s": self.cycle_time_by_target(),
                "bolls_start": self.bolls_start, "bolls_end": self.bolls_end,
                "status_changes": self.status_changes}


def write_json_atomic(path: str, data) -> None:
    """Write ``data`` as JSON to ``path`` through a temporary file in the same folder and a rename."""
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".harvest_", suffix=".json", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(json.dumps(data) + "\n")         # one string: 3x faster than json.dump(fh, indent=1)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
