"""What Cotton-Eye gave the robot over a route: counts of its outputs, as report keys (free of ROS).

The experiment recorder counts, between the route's start and end, every
row-centring status (one per segmented frame, "ok: ..." or "no_estimate: ..."),
every row-centring command (/husky/cv/coords), every correction move_base
added to its command (~vision_correction), every boll verdict
(/cotton_eye/bolls_in_reach) and the true ones, and the halts at bolls. Rates
are per second of sim time, so they say how many outputs the robot had to act
on regardless of how fast the machine ran the simulation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, Optional


@dataclass
class VisionCounts:
    row_centring_frames: int = 0      # row-centring statuses (segmented frames)
    no_estimate_frames: int = 0       # ... of them "no_estimate"
    coords: int = 0                   # row-centring commands published (frames with an estimate)
    corrections: int = 0              # control cycles in which move_base added the correction
    boll_verdicts: int = 0            # boll verdicts, all detection nodes together
    bolls_in_reach: int = 0           # ... of them true

    def add_status(self, text: str) -> None:
        """One row-centring ~status string."""
        self.row_centring_frames += 1
        self.no_estimate_frames += str(text).startswith("no_estimate")

    def add_command(self) -> None:
        """One row-centring command (/husky/cv/coords)."""
        self.coords += 1

    def add_correction(self) -> None:
        """One control cycle in which move_base added the correction."""
        self.corrections += 1

    def add_verdict(self, in_reach: bool) -> None:
        self.boll_verdicts += 1
        self.bolls_in_reach += bool(in_reach)


def _ratio(num: float, den: float) -> Optional[float]:
    return num / den if den > 0 and math.isfinite(den) else None


def vision_report(counts: VisionCounts, sim_duration_s: float) -> Dict[str, Optional[float]]:
    """The report keys (rates per sim second; fractions in [0, 1], None where nothing was counted)."""
    c = counts
    return {
        "vision_row_centring_frames": c.row_centring_frames,
        "vision_row_centring_per_sim_s": _ratio(c.row_centring_frames, sim_duration_s),
        "vision_no_estimate_fraction": _ratio(c.no_estimate_frames, c.row_centring_frames),
        "vision_coords_per_sim_s": _ratio(c.coords, sim_duration_s),
        "vision_corrections": c.corrections,
        "vision_corrections_per_sim_s": _ratio(c.corrections, sim_duration_s),
        "vision_boll_verdicts_per_sim_s": _ratio(c.boll_verdicts, sim_duration_s),
        "vision_in_reach_fraction": _ratio(c.bolls_in_reach, c.boll_verdicts),
    }
