"""What a sweep keeps of each run: its folder, written whole, and the progress line.

Layout under ``results/sweeps/<name>/`` (the tables are :mod:`.tables`)::

    sweep.yaml               the sweep file as run
    runs/<run_id>/           report.json, trajectory.csv, launch.log, sim.yaml (what the run returned)
                 outcome.json status, attempts, node, load, wall time, parameters
    runs.csv                 one row per run: parameters, status, attempts, node, RTF, the report's figures
    summary.md               per grid point, the spread of each figure over the seeds

The ``reproduce`` experiments keep their run folders elsewhere (``runs_dir``: results/gps_route/
holds seed_0/ ...). A run folder is written atomically (a temporary folder renamed into place) when
its outcome reaches the driver, so an interrupted sweep leaves only whole runs; ``--resume`` skips
the runs whose outcome says ``done``. Nothing here imports Ray or ROS.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Sequence

from .spec import RunSpec

OUTCOME_FILE = "outcome.json"
STATUS_DONE = "done"
STATUS_FAILED = "failed"
# An outcome key: a folder on the driver's machine where the run left its whole folder (a local
# cluster shares the driver's disk); write_run moves what it holds (bag, plot) into the run folder.
KEPT_DIR_KEY = "kept_dir"


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def run_dir(runs_dir: str, run_id: str) -> str:
    return os.path.join(runs_dir, run_id)


def read_json_mapping(path: str) -> Optional[Dict[str, Any]]:
    """A JSON file holding a mapping, or None when it is missing, unreadable or not a mapping."""
    try:
        with open(path, "r", encoding="utf-8") as fh:
            data = json.load(fh)
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def read_outcome(runs_dir: str, run_id: str) -> Optional[Dict[str, Any]]:
    """A run's outcome.json, or None when the run has not finished (or the file is unreadable)."""
    return read_json_mapping(os.path.join(run_dir(runs_dir, run_id), OUTCOME_FILE))


def read_run_report(runs_dir: str, run_id: str) -> Optional[Dict[str, Any]]:
    """A run's report.json, or None."""
    return read_json_mapping(os.path.join(run_dir(runs_dir, run_id), "report.json"))


def finished_run_ids(runs_dir: str, runs: Sequence[RunSpec]) -> List[str]:
    """The runs of ``runs`` whose folder holds an outcome with status ``done`` (``--resume`` skips them)."""
    return [r.run_id for r in runs if (read_outcome(runs_dir, r.run_id) or {}).get("status") == STATUS_DONE]


def outcome_report(outcome: Mapping[str, Any]) -> Optional[Dict[str, Any]]:
    """The report.json a run returned (parsed), or None."""
    text = (outcome.get("files") or {}).get("report.json")
    if text is None:
        return None
    try:
        report = json.loads(text)
    except ValueError:
        return None
    return report if isinstance(report, dict) else None


def write_run(runs_dir: str, run: RunSpec, outcome: Mapping[str, Any]) -> str:
    """Write a run's returned files and its outcome.json into <runs_dir>/<run_id>/, replacing an older attempt.

    ``outcome["files"]`` maps file names to their text; ``outcome["kept_dir"]``, when that folder
    exists here, holds the rest of the run's folder (moved in, then removed); everything else of
    ``outcome`` goes to outcome.json with the run's parameters.
    """
    final = run_dir(runs_dir, run.run_id)
    os.makedirs(runs_dir, exist_ok=True)
    staging = tempfile.mkdtemp(prefix=f".{run.run_id}.", dir=runs_dir)
    files = outcome.get("files") or {}
    for name, text in files.items():
        if os.path.basename(name) != name or name in ("", ".", "..", OUTCOME_FILE):
            shutil.rmtree(staging, ignore_errors=True)
            raise ValueError(f"run {run.run_id} returned a file named {name!r}")
        with open(os.path.join(staging, name), "w", encoding="utf-8") as fh:
            fh.write(text)
    kept = outcome.get(KEPT_DIR_KEY)
    if kept and os.path.isdir(kept):
        for name in os.listdir(kept):
            if name not in files and name != OUTCOME_FILE:
                shutil.move(os.path.join(kept, name), os.path.join(staging, name))
        shutil.rmtree(kept, ignore_errors=True)
    record = {k: v for k, v in outcome.items() if k not in ("files", KEPT_DIR_KEY)}
    record.update(run_id=run.run_id, experiment=run.experiment, seed=run.seed, parameters=dict(run.parameters),
                  files=sorted(os.listdir(staging)))
    with open(os.path.join(staging, OUTCOME_FILE), "w", encoding="utf-8") as fh:
        json.dump(record, fh, indent=1, allow_nan=True)
        fh.write("\n")
    os.chmod(staging, 0o777 & ~_umask())            # a folder like any other (mkdtemp made it 0700)
    if os.path.isdir(final):
        shutil.rmtree(final)
    os.rename(staging, final)
    return final


@dataclass
class Progress:
    """Counts of a sweep's runs and a finishing estimate from the wall time of the finished ones."""

    total: int
    skipped: int = 0
    done: int = 0
    failed: int = 0
    running: int = 0
    retries: int = 0
    wall_s: List[float] = field(default_factory=list)

    def counts(self) -> Dict[str, int]:
        return {k: v for k, v in self.__dict__.items() if k != "wall_s"}

    @property
    def left(self) -> int:
        return self.total - self.skipped - self.done - self.failed - self.running

    def estimate_s(self, parallel_runs: int) -> Optional[float]:
        """Seconds until the end: mean run wall time x runs not finished / runs at a time (None before the first)."""
        if not self.wall_s:
            return None
        per_run = sum(self.wall_s) / len(self.wall_s)
        return per_run * math.ceil((self.left + self.running) / max(1, parallel_runs))

    def line(self, parallel_runs: int) -> str:
        eta = self.estimate_s(parallel_runs)
        eta_text = "estimate after the first run" if eta is None else f"about {eta / 60:.1f} min left"
        skipped = f", {self.skipped} skipped (done before)" if self.skipped else ""
        retried = f", {self.retries} retried" if self.retries else ""
        return (f"{self.done} done, {self.running} running, {self.failed} failed, {self.left} left"
                f"{skipped}{retried}; {eta_text}")
