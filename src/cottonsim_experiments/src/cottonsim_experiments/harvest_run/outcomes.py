"""A harvest run's records (harvest.json, report.json) as the harvest figures' inputs: one outcome per open boll.

``boll_outcomes`` gives, for every boll on its plant at the start (optionally only those of some
plants), the fields of cottonsim_experiments.harvest.metrics.BollOutcome as a dict:

* detected: a target of the harvest node lies within ``match_radius_m`` of the boll's true centre
  (targets' world positions, matched one to one, nearest pairs first: picked targets before the other
  tried ones before the rest, since the node may hold a duplicate of a boll it picked);
* attempted: its target was picked or has failed attempts or a pick result; a boll that left its
  plant counts as attempted whether or not a target matched it (the truth says the arm took it);
* picked: it left its plant (held, in the bin or dropped at the end); in_bin: in the bin at the end;
* reason: for an attempted boll not in the bin, 'dropped' / 'held' from the truth, else its target's
  last pick result ('' when none);
* cycle_time_s: its target's cycle time (stop or previous boll's end to the release; binned bolls);
* localization_error_m: |target world position - true centre at the start| of attempted matched bolls;
* reachable: the boll's id is in ``reachable_ids`` (cottonsim_experiments.harvest.reachability);
* position_m: the true centre at the start.

``run_totals`` gives RunTotals' fields from report.json (route time = field time, the route holds'
time = picking time, contacts, real-time factor). Pure: no ROS.
"""
from __future__ import annotations

import math
from typing import Collection, Dict, List, Mapping, Optional

import numpy as np

DEFAULT_MATCH_RADIUS_M = 0.05


def _bolls(harvest: Mapping, key: str) -> List[Mapping]:
    snapshot = harvest.get(key)
    if not isinstance(snapshot, Mapping) or not isinstance(snapshot.get("bolls"), list):
        raise ValueError(f"harvest.json has no {key} (the recorder never received /sim/bolls)")
    return snapshot["bolls"]


def match_targets(target_xyz: np.ndarray, boll_xyz: np.ndarray, radius_m: float) -> Dict[int, int]:
    """Target index -> boll index, one to one, nearest pairs first, only pairs within radius_m [m]."""
    if not radius_m > 0.0:
        raise ValueError(f"match_radius_m must be > 0, got {radius_m!r}")
    if len(target_xyz) == 0 or len(boll_xyz) == 0:
        return {}
    d = np.linalg.norm(target_xyz[:, None, :] - boll_xyz[None, :, :], axis=2)
    ti, bi = np.nonzero(d <= radius_m)
    order = np.argsort(d[ti, bi], kind="stable")
    matched: Dict[int, int] = {}
    used = set()
    for k in order:
        t, b = int(ti[k]), int(bi[k])
        if t not in matched and b not in used:
            matched[t] = b
            used.add(b)
    return matched


def _tried(target: Mapping) -> bool:
    return target["state"] == "picked" or int(target["attempts"]) > 0 or bool(target["last_result"])


def boll_outcomes(harvest: Mapping, reachable_ids: Collection[int], plant_ids: Optional[Collection[int]] = None,
                  match_radius_m: float = DEFAULT_MATCH_RADIUS_M) -> List[Dict]:
    """One BollOutcome dict per boll on its plant at the start (of ``plant_ids`` when given); see the module."""
    start = [b for b in _bolls(harvest, "bolls_start") if b["state"] == "on_plant"
             and (plant_ids is None or int(b["plant"]) in plant_ids)]
    end_state = {int(b["id"]): b["state"] for b in _bolls(harvest, "bolls_end")}
    targets = [t for t in harvest.get("targets") or [] if t.get("position_world") is not None]
    cycle_times = {int(k): float(v) for k, v in (harvest.get("cycle_time_by_target_s") or {}).items()}
    boll_xyz = np.array([b["position"] for b in start], dtype=float).reshape(-1, 3)
    target_xyz = np.array([t["position_world"] for t in targets], dtype=float).reshape(-1, 3)
    # picked targets first, then the other tried ones, then the rest (a boll seen twice may have a duplicate
    # target nearer to it than the one that picked it)
    tier = [0 if t["state"] == "picked" else 1 if _tried(t) else 2 for t in targets]
    target_of_boll: Dict[int, int] = {}
    for level in (0, 1, 2):
        chosen = np.array([i for i, k in enumerate(tier) if k == level], dtype=int)
        free = np.array([i for i in range(len(start)) if i not in target_of_boll], dtype=int)
        pairs = match_targets(target_xyz[chosen].reshape(-1, 3), boll_xyz[free].reshape(-1, 3), match_radius_m)
        target_of_boll.update({int(free[b]): int(chosen[t]) for t, b in pairs.items()})
    reachable = {int(i) for i in reachable_ids}
    outcomes = []
    for index, boll in enumerate(start):
        boll_id = int(boll["id"])
        end = end_state.get(boll_id, "on_plant")
        target = targets[target_of_boll[index]] if index in target_of_boll else None
        tried = target is not None and _tried(target)
        picked = end != "on_plant"
        attempted = tried or picked
        in_bin = end == "in_bin"
        reason = ""
        if attempted and not in_bin:
            reason = end if end in ("dropped", "held") else (target["last_result"] if target else "")
        cycle = cycle_times.get(int(target["id"])) if (target is not None and in_bin) else None
        error = (float(np.linalg.norm(target_xyz[target_of_boll[index]] - boll_xyz[index]))
                 if target is not None and attempted else None)
        outcomes.append({"boll_id": boll_id, "reachable": boll_id in reachable, "detected": target is not None,
                         "attempted": attempted, "picked": picked, "in_bin": in_bin, "reason": reason,
                         "cycle_time_s": cycle, "localization_error_m": error,
                         "position_m": [float(v) for v in boll["position"]]})
    return outcomes


def _count(report: Mapping, key: str) -> int:
    value = report.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise ValueError(f"report.json has no count {key!r} (got {value!r}); the experiment recorder must report it")
    return int(value)


def run_totals(report: Mapping) -> Dict:
    """RunTotals' fields from a run's report.json (the module docstring)."""
    route_time = report.get("sim_duration_s")
    if isinstance(route_time, bool) or not isinstance(route_time, (int, float)) or not math.isfinite(route_time):
        raise ValueError(f"report.json has no sim_duration_s (got {route_time!r})")
    navigator = report.get("navigator") or {}
    hold = navigator.get("route_hold_time_s")
    rtf = report.get("real_time_factor")
    return {"field_time_s": float(route_time),
            "picking_time_s": float(hold) if isinstance(hold, (int, float)) and hold > 0 else None,
            "arm_stem_contacts": _count(report, "arm_stem_contacts"),
            "arm_leaf_contacts": _count(report, "arm_leaf_contacts"),
            "base_plant_contacts": _count(report, "plant_contacts"),
            "route_time_s": float(route_time),
            "real_time_factor": float(rtf) if isinstance(rtf, (int, float)) and math.isfinite(rtf) else None}
