"""Health of one input of a Cotton-Eye node: counts of frames received, processed, black, without an estimate
and missing, and when the input went stale or came back.

Pure bookkeeping (times in seconds of sim time, no ROS): a node calls
``received`` for each frame that arrives, ``processed`` / ``black`` /
``no_estimate`` for what became of the frames it looked at, and ``tick`` at
each of its processing slots; ``tick`` returns the changes a node should log
(:class:`HealthEvent`). A camera that stops sending (a blackout, a dropped
topic) is *stale* once its newest frame is older than ``stale_after_s``, and
fresh again with its next frame, so it is used again as soon as it comes back.
Black frames (mean intensity below ``black_max_mean``) are counted and not
run through a network; ``black_warn_frames`` of them in a row are logged once.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import List, Optional

import numpy as np


@dataclass(frozen=True)
class HealthConfig:
    """stale_after_s: an input whose newest frame is older than this is stale [s, sim time], default 1.0;
    black_max_mean: a frame whose mean intensity (0..255) is at most this is black [-], default 2.0;
    black_warn_frames: black frames in a row before a warning [-], default 10;
    no_estimate_warn_frames: frames without an estimate in a row before a warning [-], default 25
    (5 s at the segmentation's 5 Hz)."""

    stale_after_s: float = 1.0
    black_max_mean: float = 2.0
    black_warn_frames: int = 10
    no_estimate_warn_frames: int = 25

    def __post_init__(self):
        if not (isinstance(self.stale_after_s, (int, float)) and math.isfinite(self.stale_after_s)
                and self.stale_after_s > 0):
            raise ValueError(f"stale_after_s must be > 0 [s], got {self.stale_after_s!r}")
        if not (isinstance(self.black_max_mean, (int, float)) and 0.0 <= self.black_max_mean < 255.0):
            raise ValueError(f"black_max_mean must be in [0, 255), got {self.black_max_mean!r}")
        for key in ("black_warn_frames", "no_estimate_warn_frames"):
            value = getattr(self, key)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{key} must be an int >= 1, got {value!r}")

    @staticmethod
    def from_mapping(values) -> "HealthConfig":
        """A HealthConfig from the keys of ``values`` that are its fields (others ignored)."""
        names = {f.name for f in dataclasses.fields(HealthConfig)}
        return HealthConfig(**{k: v for k, v in dict(values).items() if k in names})


@dataclass(frozen=True)
class HealthEvent:
    """A change worth one log line: kind 'stale' | 'back' | 'black' | 'no_estimate'; message says what."""

    kind: str
    input_name: str
    message: str


def is_black(image: np.ndarray, black_max_mean: float) -> bool:
    """True if the image's mean intensity (over all pixels and channels, 0..255) is at most black_max_mean.

    Looks at every 4th row and column (a black frame is black everywhere; 1/16 of the pixels is enough).
    Raises ValueError for an empty image.
    """
    if image.size == 0:
        raise ValueError("is_black: empty image")
    return float(image[::4, ::4].mean()) <= black_max_mean


class InputHealth:
    """Counts and state of one input (see the module docstring)."""

    def __init__(self, name: str, config: HealthConfig = HealthConfig()):
        self.name = name
        self.config = config
        self.frames_received = 0
        self.frames_processed = 0
        self.frames_black = 0
        self.frames_no_estimate = 0
        self.frames_stale = 0
        self.stale = False
        self.last_frame_s: Optional[float] = None
        self.started_s: Optional[float] = None
        self._black_run = 0
        self._no_estimate_run = 0
        self._events: List[HealthEvent] = []

    # ------------------------------------------------------------------ what happened to frames
    def received(self, now_s: float) -> None:
        """A frame arrived at sim time now_s; a stale input is fresh again."""
        if self.stale:
            gap = now_s - self.last_frame_s if self.last_frame_s is not None else now_s - (self.started_s or now_s)
            self._events.append(HealthEvent("back", self.name, f"{self.name}: frames again after {gap:.1f} s; "
                                                               f"using it again"))
            self.stale = False
        self.frames_received += 1
        self.last_frame_s = float(now_s)

    def processed(self, has_estimate: bool = True) -> None:
        """A frame went through the network / the core; has_estimate False counts a frame without a result."""
        self.frames_processed += 1
        self._black_run = 0
        if has_estimate:
            self._no_estimate_run = 0
            return
        self.frames_no_estimate += 1
        self._no_estimate_run += 1
        if self._no_estimate_run == self.config.no_estimate_warn_frames:
            self._events.append(HealthEvent("no_estimate", self.name,
                                            f"{self.name}: no estimate for {self._no_estimate_run} frames in a row"))

    def black(self) -> None:
        """A frame was black and skipped."""
        self.frames_black += 1
        self._black_run += 1
        if self._black_run == self.config.black_warn_frames:
            self._events.append(HealthEvent("black", self.name,
                                            f"{self.name}: {self._black_run} black frames in a row; skipping them"))

    # ------------------------------------------------------------------ the node's clock
    def age_s(self, now_s: float) -> float:
        """Sim time since the newest frame arrived [s], or -1 before the first."""
        return -1.0 if self.last_frame_s is None else max(0.0, now_s - self.last_frame_s)

    def tick(self, now_s: float) -> List[HealthEvent]:
        """A processing slot at sim time now_s: counts it as stale if the input is; returns new events."""
        if self.started_s is None or now_s < self.started_s:        # first slot, or the clock went back
            self.started_s = float(now_s)
        since = self.last_frame_s if self.last_frame_s is not None else self.started_s
        if now_s - since > self.config.stale_after_s:
            self.frames_stale += 1
            if not self.stale:
                self.stale = True
                what = "no frame yet" if self.last_frame_s is None else f"no frame for {now_s - since:.1f} s"
                self._events.append(HealthEvent("stale", self.name, f"{self.name}: {what}; going on without it"))
        events, self._events = self._events, []
        return events
