"""Render a dataset on Ray: scenes cut into ranges, one Ray task per range, the driver writes.

A range is a contiguous block of scene indices of one task of one ``FarmJob``.
Its task renders those scenes and returns the encoded images and label texts
(``EncodedImage``); it writes nothing, so a range whose worker died can simply
run again (Ray's ``max_retries``). Every draw depends only on (dataset_seed,
farm seed, task, scene / image index), so the files are byte-identical to the
worker-pool path whatever the cluster or the range size. Ray is imported only
here, and only when this engine is used.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable, List, Optional

from cottonsim_common.validation import require_int

from .config import DatasetConfig
from .pipeline import EncodedImage, FarmJob, ImageRecord, render_scene_range, scene_count, write_encoded_image


@dataclass(frozen=True)
class RayEngineConfig:
    """Where and how the ranges run.

    address: None starts a local cluster of ``num_cpus`` cores; "auto" or
      "HOST:PORT" joins a running cluster.
    num_cpus: cores of the local cluster (None: this machine's cores).
    scenes_per_range: scenes per Ray task (>= 1).
    max_retries: times a range whose worker died runs again (>= 0).
    """

    address: Optional[str] = None
    num_cpus: Optional[int] = None
    scenes_per_range: int = 1
    max_retries: int = 3

    def __post_init__(self) -> None:
        check_address(self.address)
        if self.num_cpus is not None:
            require_int("num_cpus", self.num_cpus, 1)
        require_int("scenes_per_range", self.scenes_per_range, 1)
        require_int("max_retries", self.max_retries, 0)


def check_address(address: Optional[str]) -> None:
    """ValueError unless ``address`` is None, 'auto' or 'HOST:PORT' with a port in 1..65535."""
    if address is None or address == "auto":
        return
    host, sep, port = str(address).rpartition(":")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ValueError(f"address must be 'auto' or 'HOST:PORT' (port 1-65535), got {address!r}")


@dataclass(frozen=True)
class SceneRange:
    """Scenes [scene_lo, scene_hi) of one task of one farm job."""

    job: FarmJob
    task: str
    scene_lo: int
    scene_hi: int

    def images(self, config: DatasetConfig) -> int:
        count = dict(self.job.counts)[self.task]
        per = config.images_per_scene
        return max(0, min(count, self.scene_hi * per) - self.scene_lo * per)


def plan_ranges(config: DatasetConfig, jobs: List[FarmJob], scenes_per_range: int) -> List[SceneRange]:
    """Every scene of every job cut into ranges of ``scenes_per_range`` scenes (the last may be shorter)."""
    ranges = []
    for job in jobs:
        for task, count in job.counts:
            n = scene_count(config, count)
            for lo in range(0, n, scenes_per_range):
                ranges.append(SceneRange(job, task, lo, min(n, lo + scenes_per_range)))
    return ranges


def _render_range(config: DatasetConfig, scene_range: SceneRange) -> List[EncodedImage]:
    return list(render_scene_range(config, scene_range.job, scene_range.task,
                                   scene_range.scene_lo, scene_range.scene_hi))


def run_on_ray(config: DatasetConfig, jobs: List[FarmJob], engine: RayEngineConfig,
               on_progress: Optional[Callable[[int], None]] = None,
               poll_s: float = 1.0) -> List[ImageRecord]:
    """Render every range of ``jobs`` as Ray tasks and write their files here; returns the records.

    ConnectionError when the cluster at ``engine.address`` cannot be joined.
    """
    import ray

    started_here = not ray.is_initialized()
    if started_here:
        try:
            if engine.address:
                ray.init(address=engine.address, log_to_driver=False, include_dashboard=False)
            else:
                ray.init(num_cpus=engine.num_cpus or os.cpu_count(), log_to_driver=False,
                         include_dashboard=False)
        except Exception as exc:    # ray raises ConnectionError, RuntimeError or ValueError here
            raise ConnectionError(f"could not join the Ray cluster at {engine.address!r}: {exc}") from exc
    try:
        remote = ray.remote(_render_range).options(num_cpus=1, max_retries=engine.max_retries)
        config_ref = ray.put(config)
        pending = {remote.remote(config_ref, r): r for r in plan_ranges(config, jobs, engine.scenes_per_range)}
        records: List[ImageRecord] = []
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=poll_s)
            for ref in ready:
                scene_range = pending.pop(ref)
                for item in ray.get(ref):      # re-raises a range's exception
                    records.append(write_encoded_image(config, scene_range.job.split, item))
            if on_progress is not None:
                on_progress(len(records))
        return records
    finally:
        if started_here:
            ray.shutdown()
