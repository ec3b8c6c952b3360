"""The harvest's figures from a run's plain records, as cotton-picking robots are judged.

Input: one ``BollOutcome`` per boll that was open at the start of the run (or a dict with
its fields: ``reproduce harvest`` and the harvest node's summary both produce them) and
one ``RunTotals``. Output (``harvest_figures``), a flat dict:

* counts: open_bolls, reachable, detected, attempted, picked (captured by the nozzle),
  in_bin; misses by reason (``miss_reasons``, the pick results' reasons);
* the funnel of Bac et al. 2014 over the reachable bolls: localisation (detected /
  reachable), pick (picked / attempted), bin (in_bin / picked), each stage with its count;
* harvest_success_percent = in_bin (reachable ones) / reachable; field_harvest_percent =
  in_bin / open_bolls;
* cycle time per boll (stop or previous boll's end to its release over the bin) of the
  binned bolls: median and 95th percentile [s]; bolls_per_hour over the field time
  (driving included) and, when picking_time_s is given, over the picking time alone;
* 3-D localisation error of the picked targets against the truth: median, p95 [m];
* contacts: arm-stem, arm-leaf, base-plant; route_time_s and real_time_factor as given.

A figure whose population is empty is None (JSON null), never a made-up 0 or 100.
``ANCHORS`` are the published figures of real robots that the issue compares with.
"""
from __future__ import annotations

import collections
import math
from dataclasses import dataclass, fields
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Union

import numpy as np

ANCHORS = {
    "Fue et al. 2020 (2-axis Cartesian arm, vacuum + tines, field)": {
        "reached_percent": 95.0, "harvest_success_percent": 78.5, "localization_error_mm": "9 standing, 34 moving"},
    "Singh et al. 2024 (4-DoF arm, vacuum)": {
        "harvest_success_percent": "76-86 lab, 66-72 field", "cycle_time_s": "73-86", "bolls_per_hour": "40-49"},
    "Bac et al. 2014 (review of 50 harvesting robots)": {"harvest_success_percent": 66.0, "cycle_time_s": 33.0},
}


@dataclass(frozen=True)
class BollOutcome:
    """What happened to one boll open at the start (world truth and the robot's records).

    reachable: from the route (harvest/reachability.py); detected: it became a target of the
    harvest node; attempted: a pick of it began; picked: the nozzle captured it; in_bin: it
    ended in the bin. reason: the pick result's reason when attempted and not binned ('' else).
    cycle_time_s: stop (or previous boll's end) to its release over the bin [s], binned bolls.
    localization_error_m: |target estimate - true centre| at the pick [m], attempted bolls.
    """

    boll_id: int
    reachable: bool = False
    detected: bool = False
    attempted: bool = False
    picked: bool = False
    in_bin: bool = False
    reason: str = ""
    cycle_time_s: Optional[float] = None
    localization_error_m: Optional[float] = None
    position_m: Optional[Sequence[float]] = None

    def __post_init__(self) -> None:
        if isinstance(self.boll_id, bool) or not isinstance(self.boll_id, (int, np.integer)):
            raise ValueError(f"BollOutcome.boll_id must be an integer, got {self.boll_id!r}")
        for name in ("reachable", "detected", "attempted", "picked", "in_bin"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"boll {self.boll_id}: {name} must be true or false, got {getattr(self, name)!r}")
        for name in ("cycle_time_s", "localization_error_m"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                                  or v < 0.0):
                raise ValueError(f"boll {self.boll_id}: {name} must be a finite number >= 0 or None, got {v!r}")
        if self.in_bin and not self.picked or self.picked and not self.attempted:
            raise ValueError(f"boll {self.boll_id}: in_bin needs picked and picked needs attempted")


@dataclass(frozen=True)
class RunTotals:
    """The run as a whole: field_time_s (route start to end, driving and picking) [s]; picking_time_s
    (the arm's stops only, None = not recorded) [s]; the contact events; route time and RTF as reported."""

    field_time_s: float
    picking_time_s: Optional[float] = None
    arm_stem_contacts: int = 0
    arm_leaf_contacts: int = 0
    base_plant_contacts: int = 0
    route_time_s: Optional[float] = None
    real_time_factor: Optional[float] = None

    def __post_init__(self) -> None:
        for name in ("field_time_s", "picking_time_s", "route_time_s", "real_time_factor"):
            v = getattr(self, name)
            if v is None and name != "field_time_s":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0.0:
                raise ValueError(f"RunTotals.{name} must be a finite number >= 0, got {v!r}")
        for name in ("arm_stem_contacts", "arm_leaf_contacts", "base_plant_contacts"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                raise ValueError(f"RunTotals.{name} must be an integer >= 0, got {v!r}")


def _record(cls, item, what: str):
    if isinstance(item, cls):
        return item
    if not isinstance(item, Mapping):
        raise ValueError(f"{what} must be a {cls.__name__} or a mapping of its fields, got {type(item).__name__}")
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(item) - known)
    if unknown:
        raise ValueError(f"{what}: unknown field(s) {unknown} (known: {sorted(known)})")
    try:
        return cls(**item)
    except TypeError as exc:
        raise ValueError(f"{what}: {exc}") from None


def _percent(part: int, whole: int) -> Optional[float]:
    return 100.0 * part / whole if whole else None


def _quantiles(values: List[float]) -> Dict[str, Optional[float]]:
    if not values:
        return {"median": None, "p95": None}
    return {"median": float(np.median(values)), "p95": float(np.percentile(values, 95))}


def harvest_figures(outcomes: Iterable[Union[BollOutcome, Mapping]], run: Union[RunTotals, Mapping]) -> Dict:
    """The harvest's figures (see the module docstring) from every open boll's outcome and the run's totals."""
    bolls = [_record(BollOutcome, o, f"outcome {i}") for i, o in enumerate(outcomes)]
    run = _record(RunTotals, run, "run")
    ids = [b.boll_id for b in bolls]
    if len(set(ids)) != len(ids):
        dup = sorted(i for i, n in collections.Counter(ids).items() if n > 1)
        raise ValueError(f"boll ids must be unique, repeated: {dup}")
    reachable = [b for b in bolls if b.reachable]
    count = {name: sum(getattr(b, name) for b in bolls) for name in ("reachable", "detected", "attempted", "picked",
                                                                     "in_bin")}
    detected_reachable = sum(b.detected for b in reachable)
    binned_reachable = sum(b.in_bin for b in reachable)
    cycle = [b.cycle_time_s for b in bolls if b.in_bin and b.cycle_time_s is not None]
    error = [b.localization_error_m for b in bolls if b.picked and b.localization_error_m is not None]
    hours = run.field_time_s / 3600.0
    figures = {
        "open_bolls": len(bolls), **count,
        "miss_reasons": dict(sorted(collections.Counter(b.reason or "not_attempted" for b in reachable
                                                        if not b.in_bin).items())),
        "funnel": [
            {"stage": "reachable", "count": len(reachable), "percent_of_previous": None},
            {"stage": "localisation", "count": detected_reachable,
             "percent_of_previous": _percent(detected_reachable, len(reachable))},
            {"stage": "pick", "count": count["picked"], "percent_of_previous": _percent(count["picked"],
                                                                                       count["attempted"])},
            {"stage": "bin", "count": count["in_bin"], "percent_of_previous": _percent(count["in_bin"],
                                                                                      count["picked"])},
        ],
        "harvest_success_percent": _percent(binned_reachable, len(reachable)),
        "field_harvest_percent": _percent(count["in_bin"], len(bolls)),
        "cycle_time_s": _quantiles(cycle),
        "bolls_per_hour": count["in_bin"] / hours if hours > 0.0 else None,
        "bolls_per_hour_picking": (count["in_bin"] / (run.picking_time_s / 3600.0)
                                   if run.picking_time_s else None),
        "localization_error_m": _quantiles(error),
        "arm_stem_contacts": run.arm_stem_contacts,
        "arm_leaf_contacts": run.arm_leaf_contacts,
        "base_plant_contacts": run.base_plant_contacts,
        "route_time_s": run.route_time_s,
        "real_time_factor": run.real_time_factor,
    }
    return figures
