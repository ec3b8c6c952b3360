"""The paper's row-spacing study (its Fig. 3a): which spacing can the robot traverse?

The paper drove the robot into pairs of cotton rows 1.0 to 1.9 m apart (0.1 m
steps) and found 1.8 m to be the narrowest the robot traverses: closer rows
put the canopies inside the LiDAR's obstacle margin and navigation stops the
robot. Here every attempt is one complete GPS-navigation bringup (simulator,
localisation, move_base with its LiDAR costmaps, waypoint navigator,
experiment recorder) on a small farm of ``rows`` rows at the tested spacing.
The tested lane (between row 0 and row 1) lies straight ahead of Home, and
the route has three waypoints on its centre line like each lane of the
paper's route: entry, middle, exit.

An attempt *traverses* the lane when every waypoint is reached without a
single plant contact. This module plans the attempts, builds each attempt's
farm settings and route, reads an attempt's report.json into an
:class:`AttemptOutcome`, and summarises the study; running the bringups is the
job of :mod:`.launcher` and the ``reproduce`` command.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

# The paper's ten spacings [m].
PAPER_SPACINGS_M: Tuple[float, ...] = tuple(round(1.0 + 0.1 * k, 2) for k in range(10))
PAPER_SMALLEST_SPACING_M = 1.8


@dataclass(frozen=True)
class RowSpacingStudyConfig:
    """What the study tests.

    spacings_m: row spacings to try [m], each > plant width.
    rows: rows of the test farm (>= 2; the lane between rows 0 and 1 is driven).
    plants_per_row: plants per row (20 as the paper's farm).
    lane_x_m: world x of the tested lane's centre line [m]; the default puts
        it straight ahead of the default Home (x = -6 m, facing +y).
    goal_timeout_s: sim time after which a waypoint counts as failed [s].
    seed: farm and simulator seed.
    """

    spacings_m: Tuple[float, ...] = PAPER_SPACINGS_M
    rows: int = 2
    plants_per_row: int = 20
    lane_x_m: float = -6.0
    goal_timeout_s: float = 90.0
    seed: int = 0

    def __post_init__(self) -> None:
        spacings = tuple(float(s) for s in self.spacings_m)
        if not spacings:
            raise ValueError("spacings_m must list at least one spacing")
        for s in spacings:
            if not math.isfinite(s) or s <= 0.0:
                raise ValueError(f"spacings_m must hold finite spacings > 0 m, got {s!r}")
        object.__setattr__(self, "spacings_m", tuple(sorted(set(spacings))))
        if int(self.rows) != self.rows or self.rows < 2:
            raise ValueError(f"rows must be an integer >= 2 (the driven lane lies between two rows), got {self.rows!r}")
        if int(self.plants_per_row) != self.plants_per_row or self.plants_per_row < 1:
            raise ValueError(f"plants_per_row must be an integer >= 1, got {self.plants_per_row!r}")
        if not math.isfinite(self.lane_x_m):
            raise ValueError(f"lane_x_m must be finite, got {self.lane_x_m!r}")
        if not self.goal_timeout_s > 0.0:
            raise ValueError(f"goal_timeout_s must be > 0 s, got {self.goal_timeout_s!r}")
        if int(self.seed) != self.seed or self.seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")


def attempt_farm_settings(config: RowSpacingStudyConfig, spacing_m: float) -> Dict[str, object]:
    """The ``farm:`` settings (FarmConfig keys) of the attempt at ``spacing_m``.

    Lane 1 (between rows 0 and 1) sits at ``config.lane_x_m``; the lane-fit
    check is off because narrow spacings are the point of the study.
    """
    if not spacing_m > 0.0:
        raise ValueError(f"spacing_m must be > 0, got {spacing_m!r}")
    return {
        "rows": int(config.rows),
        "plants_per_row": int(config.plants_per_row),
        "row_spacing_m": float(spacing_m),
        "first_lane_x_m": float(config.lane_x_m + spacing_m),
        "require_lane_fit": False,
        "seed": int(config.seed),
    }


def attempt_route_world(farm_config) -> List[Tuple[float, float]]:
    """Entry, middle and exit of lane 1 on its centre line, world x/y [m].

    ``farm_config`` is a cottonsim_world FarmConfig (entry/exit distances and
    the plants' extent come from it).
    """
    x = farm_config.lane_x_m(1)
    y_first = farm_config.first_plant_y_m
    y_last = y_first + farm_config.plant_spacing_m * (farm_config.plants_per_row - 1)
    return [(x, y_first - farm_config.route_entry_distance_m),
            (x, 0.5 * (y_first + y_last)),
            (x, y_last + farm_config.route_exit_distance_m)]


@dataclass(frozen=True)
class AttemptOutcome:
    """One attempt, read from its report.json."""

    spacing_m: float
    free_lane_m: float        # spacing - plant width: the gap between the canopies [m]
    traversed: bool           # every waypoint reached and no plant contact
    reached: int
    waypoints: int
    plant_contacts: int
    reason: str               # why it failed ("" when traversed)
    sim_duration_s: float
    cross_track_max_m: Optional[float]
    lane_progress_m: Optional[float] = None   # how far past the first stems the robot got [m] (None: unknown)
    lane_length_m: Optional[float] = None     # first to last stem [m]

    def to_dict(self) -> Dict[str, object]:
        return asdict(self)


def lane_progress_m(trajectory_y_m: Sequence[float], farm_config) -> Tuple[float, float]:
    """How far into lane 1 the robot got (its northmost y past the first stems) and the lane's length [m]."""
    length = farm_config.plant_spacing_m * (farm_config.plants_per_row - 1)
    if len(trajectory_y_m) == 0:
        return 0.0, length
    progress = max(float(y) for y in trajectory_y_m) - farm_config.first_plant_y_m
    return min(max(progress, 0.0), length), length


def outcome_from_report(spacing_m: float, plant_width_m: float, report: Optional[Mapping[str, object]],
                        launch_error: str = "", progress: Optional[Tuple[float, float]] = None) -> AttemptOutcome:
    """Classify one attempt from its report (None: the bringup wrote none).

    ``progress`` = (lane progress [m], lane length [m]) from the trajectory,
    when known: a failed attempt then says where the robot stopped.
    """
    free = float(spacing_m) - float(plant_width_m)
    done_m, length_m = progress if progress is not None else (None, None)
    if report is None:
        return AttemptOutcome(spacing_m, free, False, 0, 0, 0,
                              launch_error or "no report written (the bringup failed to start or was killed)",
                              float("nan"), None, done_m, length_m)
    waypoints = int(report.get("waypoints", 0))
    reached = int(report.get("reached", 0))
    contacts = int(report.get("plant_contacts", 0))
    reasons = []
    if not report.get("complete", True):
        reasons.append(f"run incomplete: {report.get('incomplete_reason') or 'stopped early'}")
    if reached < waypoints:
        nav = report.get("navigator") or {}
        nav_reason = nav.get("reason") if isinstance(nav, Mapping) else None
        aborted = nav.get("aborted") if isinstance(nav, Mapping) else None
        detail = f"{reached}/{waypoints} waypoints reached"
        if aborted:
            detail += f", {aborted} aborted"
        if nav_reason:
            detail += f" ({nav_reason})"
        reasons.append(detail)
    if contacts > 0:
        reasons.append(f"{contacts} plant contacts")
    if reasons and done_m is not None and length_m and done_m < length_m - 1e-6:
        reasons.insert(0, f"stopped {done_m:.1f} m into the {length_m:.1f} m row")
    if launch_error:
        reasons.append(launch_error)
    cross_max = report.get("cross_track_max_m")
    return AttemptOutcome(
        spacing_m=float(spacing_m), free_lane_m=free,
        traversed=not reasons and waypoints > 0,
        reached=reached, waypoints=waypoints, plant_contacts=contacts,
        reason="; ".join(reasons) if reasons else ("" if waypoints > 0 else "empty route"),
        sim_duration_s=float(report.get("sim_duration_s", float("nan"))),
        cross_track_max_m=None if cross_max is None else float(cross_max),
        lane_progress_m=done_m, lane_length_m=length_m)


def smallest_traversable_spacing(outcomes: Sequence[AttemptOutcome]) -> Optional[float]:
    """The smallest tested spacing from which every wider tested spacing is traversed too.

    A narrow spacing that happens to pass while a wider one fails does not
    count: the answer is the lower end of the run of successes that reaches
    the widest spacing tested. None when the widest spacing fails.
    """
    ordered = sorted(outcomes, key=lambda o: o.spacing_m)
    best = None
    for o in reversed(ordered):
        if not o.traversed:
            break
        best = o.spacing_m
    return best


def contact_free_spacing_m(robot_width_m: float, plant_collision_radius_m: float) -> float:
    """The narrowest spacing at which a robot centred in the lane clears the plants' collision shapes [m].

    The lane's stems are one spacing apart; the robot (half its width each
    side of the centre line) touches a plant whose collision radius reaches
    past the remaining half spacing.
    """
    return float(robot_width_m) + 2.0 * float(plant_collision_radius_m)


def study_summary(config: RowSpacingStudyConfig, outcomes: Sequence[AttemptOutcome],
                  robot_width_m: float, plant_collision_radius_m: Optional[float] = None) -> Dict[str, object]:
    """JSON-ready summary: per-spacing outcomes, the smallest traversable spacing, the paper's.

    plant_collision_radius_m: the widest collision radius of the study's plants
    [m], for the geometric explanation (None: unknown).
    """
    smallest = smallest_traversable_spacing(outcomes)
    return {
        "experiment": "row_spacing",
        "spacings_m": list(config.spacings_m),
        "rows": config.rows,
        "plants_per_row": config.plants_per_row,
        "seed": config.seed,
        "robot_width_m": robot_width_m,
        "plant_collision_radius_m": plant_collision_radius_m,
        "contact_free_spacing_m": (None if plant_collision_radius_m is None
                                   else contact_free_spacing_m(robot_width_m, plant_collision_radius_m)),
        "smallest_traversable_spacing_m": smallest,
        "paper_smallest_spacing_m": PAPER_SMALLEST_SPACING_M,
        "attempts": [o.to_dict() for o in sorted(outcomes, key=lambda o: o.spacing_m)],
    }


def summary_markdown(summary: Mapping[str, object]) -> str:
    """A Markdown table of the study (one row per spacing) and its conclusion."""
    lines = ["| spacing [m] | free lane [m] | traversed | waypoints | plant contacts | why not |",
             "|---|---|---|---|---|---|"]
    for a in summary["attempts"]:
        lines.append(f"| {a['spacing_m']:.2f} | {a['free_lane_m']:.2f} | {'yes' if a['traversed'] else 'no'} | "
                     f"{a['reached']}/{a['waypoints']} | {a['plant_contacts']} | {a['reason'] or '-'} |")
    smallest = summary.get("smallest_traversable_spacing_m")
    lines.append("")
    lines.append("Smallest spacing traversed without plant contacts (with every wider one): "
                 + (f"**{smallest:.2f} m**" if smallest is not None else "**none**")
                 + f" (paper: {summary.get('paper_smallest_spacing_m', PAPER_SMALLEST_SPACING_M):.2f} m).")
    return "\n".join(lines)


def seeds_summary(per_seed: Sequence[Mapping[str, object]]) -> Dict[str, object]:
    """The study over several seeds: per spacing, in how many seeds it was traversed; the spread of the answer.

    ``per_seed``: :func:`study_summary` dicts of the same spacings, one per seed.
    A seed whose widest spacing failed has no answer and is counted in
    ``seeds_without_answer``.
    """
    from .seeds import spread

    if not per_seed:
        raise ValueError("per_seed must hold at least one study summary")
    spacings = sorted({round(a["spacing_m"], 6) for s in per_seed for a in s["attempts"]})
    rows = []
    for sp in spacings:
        attempts = [a for s in per_seed for a in s["attempts"] if abs(a["spacing_m"] - sp) < 1e-6]
        failed = [a for a in attempts if not a["traversed"]]
        rows.append({"spacing_m": sp, "free_lane_m": attempts[0]["free_lane_m"], "attempts": len(attempts),
                     "traversed": len(attempts) - len(failed),
                     "plant_contacts_mean": sum(a["plant_contacts"] for a in attempts) / len(attempts),
                     "why_not": failed[0]["reason"] if failed else ""})
    answers = [s["smallest_traversable_spacing_m"] for s in per_seed]
    found = [a for a in answers if a is not None]
    return {"experiment": "row_spacing", "seeds": [s["seed"] for s in per_seed], "spacings": rows,
            "smallest_traversable_spacing_m": spread(found) if found else None,
            "seeds_without_answer": len(answers) - len(found),
            "paper_smallest_spacing_m": PAPER_SMALLEST_SPACING_M, "per_seed": list(per_seed)}


def seeds_markdown(summary: Mapping[str, object]) -> str:
    """Markdown of :func:`seeds_summary`: one row per spacing and the conclusion with its spread."""
    n = len(summary["seeds"])
    lines = [f"Seeds {summary['seeds']}.", "",
             "| spacing [m] | free lane [m] | traversed (seeds) | plant contacts (mean) | why not (first failing seed) |",
             "|---|---|---|---|---|"]
    for r in summary["spacings"]:
        lines.append(f"| {r['spacing_m']:.2f} | {r['free_lane_m']:.2f} | {r['traversed']}/{r['attempts']} | "
                     f"{r['plant_contacts_mean']:.1f} | {r['why_not'] or '-'} |")
    st = summary.get("smallest_traversable_spacing_m")
    if st is None:
        answer = "**none** (the widest spacing failed in every seed)"
    elif st["n"] == 1:
        answer = f"**{st['mean']:.2f} m** (one seed)"
    else:
        answer = f"**{st['mean']:.2f} m** (± {st['std']:.2f} m over {st['n']} seeds, {st['min']:.2f}..{st['max']:.2f})"
    missing = summary.get("seeds_without_answer", 0)
    lines += ["", f"Smallest spacing traversed without plant contacts (with every wider one): {answer}"
              + (f"; {missing} of {n} seeds had no traversable spacing" if missing else "")
              + f" (paper: {summary.get('paper_smallest_spacing_m', PAPER_SMALLEST_SPACING_M):.2f} m)."]
    return "\n".join(lines)
