"""What a sweep keeps: one folder per run, runs.csv, summary.md, and the progress line.

Layout under ``results/sweeps/<name>/``::

    sweep.yaml               the sweep file as run
    runs/<run_id>/           report.json, trajectory.csv, launch.log, sim.yaml (what the run returned)
                 outcome.json status, attempts, node, load, wall time, parameters
    runs.csv                 one row per run: parameters, status, attempts, node, RTF, the report's figures
    summary.md               per grid point, the spread of each figure over the seeds

A run folder is written atomically (a temporary folder renamed into place) when its outcome reaches
the driver, so an interrupted sweep leaves only whole runs; ``--resume`` skips the runs whose
outcome says ``done``. Nothing here imports Ray or ROS.
"""
from __future__ import annotations

import csv
import json
import math
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Sequence

from ..reproduce.seeds import aggregate_reports, format_spread
from .spec import RunSpec

# The report's figures copied into runs.csv and summarised in summary.md.
FIGURES = ("complete", "cr_percent", "cr_percent_010m", "ae_m", "rmse_m", "cross_track_mean_m", "cross_track_max_m",
           "plant_contacts", "sim_duration_s", "real_time_factor")
RUN_COLUMNS = ("run_id", "seed", "status", "attempts", "node", "ray_node", "load_average_1m", "wall_s", "error")
OUTCOME_FILE = "outcome.json"
STATUS_DONE = "done"
STATUS_FAILED = "failed"


def run_dir(sweep_dir: str, run_id: str) -> str:
    return os.path.join(sweep_dir, "runs", run_id)


def read_outcome(sweep_dir: str, run_id: str) -> Optional[Dict[str, Any]]:
    """A run's outcome.json, or None when the run has not finished (or the file is unreadable)."""
    try:
        with open(os.path.join(run_dir(sweep_dir, run_id), OUTCOME_FILE), "r", encoding="utf-8") as fh:
            outcome = json.load(fh)
    except (OSError, ValueError):
        return None
    return outcome if isinstance(outcome, dict) else None


def finished_run_ids(sweep_dir: str, runs: Sequence[RunSpec]) -> List[str]:
    """The runs of ``runs`` whose folder holds an outcome with status ``done`` (``--resume`` skips them)."""
    return [r.run_id for r in runs if (read_outcome(sweep_dir, r.run_id) or {}).get("status") == STATUS_DONE]


def write_run(sweep_dir: str, run: RunSpec, outcome: Mapping[str, Any]) -> str:
    """Write a run's returned files and its outcome.json into runs/<run_id>/, replacing an older attempt.

    ``outcome["files"]`` maps file names to their text; everything else of ``outcome`` goes to
    outcome.json with the run's parameters.
    """
    final = run_dir(sweep_dir, run.run_id)
    os.makedirs(os.path.dirname(final), exist_ok=True)
    staging = tempfile.mkdtemp(prefix=f".{run.run_id}.", dir=os.path.dirname(final))
    for name, text in (outcome.get("files") or {}).items():
        if os.path.basename(name) != name or name in ("", ".", "..", OUTCOME_FILE):
            raise ValueError(f"run {run.run_id} returned a file named {name!r}")
        with open(os.path.join(staging, name), "w", encoding="utf-8") as fh:
            fh.write(text)
    record = {k: v for k, v in outcome.items() if k != "files"}
    record.update(run_id=run.run_id, experiment=run.experiment, seed=run.seed, parameters=dict(run.parameters),
                  files=sorted((outcome.get("files") or {}).keys()))
    with open(os.path.join(staging, OUTCOME_FILE), "w", encoding="utf-8") as fh:
        json.dump(record, fh, indent=1, allow_nan=True)
        fh.write("\n")
    if os.path.isdir(final):
        shutil.rmtree(final)
    os.rename(staging, final)
    return final


def _report(sweep_dir: str, run_id: str) -> Optional[Dict[str, Any]]:
    try:
        with open(os.path.join(run_dir(sweep_dir, run_id), "report.json"), "r", encoding="utf-8") as fh:
            report = json.load(fh)
    except (OSError, ValueError):
        return None
    return report if isinstance(report, dict) else None


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.6g}"
    return "" if value is None else value


def write_tables(sweep_dir: str, runs: Sequence[RunSpec]) -> Dict[str, str]:
    """runs.csv and summary.md from the run folders (runs without an outcome are listed as 'missing')."""
    parameter_keys = sorted({k for r in runs for k in r.parameters})
    rows = []
    for run in runs:
        outcome = read_outcome(sweep_dir, run.run_id) or {"status": "missing"}
        report = _report(sweep_dir, run.run_id) or {}
        row = {"run_id": run.run_id, "seed": run.seed}
        row.update({k: run.parameters.get(k) for k in parameter_keys})
        row.update({k: outcome.get(k) for k in RUN_COLUMNS if k not in ("run_id", "seed")})
        row.update({k: report.get(k) for k in FIGURES})
        rows.append(row)
    csv_path = os.path.join(sweep_dir, "runs.csv")
    columns = ["run_id", "seed", *parameter_keys, *RUN_COLUMNS[2:], *FIGURES]
    with open(csv_path, "w", encoding="utf-8", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _cell(row.get(k)) for k in columns})
    md_path = os.path.join(sweep_dir, "summary.md")
    with open(md_path, "w", encoding="utf-8") as fh:
        fh.write(summary_markdown(sweep_dir, runs, parameter_keys) + "\n")
    return {"runs_csv": csv_path, "summary_md": md_path}


# (figure, column title, scale, digits) of summary.md
_SUMMARY_FIGURES = (("cr_percent", "CR 5e-6 deg [%]", 1.0, 1), ("cr_percent_010m", "CR 0.10 m [%]", 1.0, 1),
                    ("ae_m", "AE [m]", 1.0, 3), ("rmse_m", "RMSE [m]", 1.0, 3),
                    ("cross_track_mean_m", "in-row cross-track mean [cm]", 100.0, 2),
                    ("plant_contacts", "plant contacts", 1.0, 1), ("sim_duration_s", "route [min]", 1 / 60, 2),
                    ("real_time_factor", "RTF", 1.0, 2))


def summary_markdown(sweep_dir: str, runs: Sequence[RunSpec], parameter_keys: Sequence[str]) -> str:
    """One row per grid point: the spread of each figure over its seeds ('mean ± std (min..max, n)')."""
    groups: Dict[tuple, List[RunSpec]] = {}
    for run in runs:
        groups.setdefault(tuple(run.parameters.get(k) for k in parameter_keys), []).append(run)
    status = [(read_outcome(sweep_dir, r.run_id) or {}).get("status", "missing") for r in runs]
    lines = [f"# Sweep {os.path.basename(os.path.normpath(sweep_dir))}", "",
             f"{len(runs)} runs: {status.count(STATUS_DONE)} done, {status.count(STATUS_FAILED)} failed, "
             f"{status.count('missing')} not run. Each cell: mean ± std (min..max, n) over the seeds.", ""]
    header = [*parameter_keys, "runs with a report", *(title for _, title, _, _ in _SUMMARY_FIGURES)]
    lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for key, members in groups.items():
        reports = [rep for rep in (_report(sweep_dir, r.run_id) for r in members) if rep is not None]
        stats = aggregate_reports(reports, [f for f, _, _, _ in _SUMMARY_FIGURES])
        cells = [str(v) for v in key] + [f"{len(reports)}/{len(members)}"]
        cells += [format_spread(stats.get(f, {}), scale, digits) for f, _, scale, digits in _SUMMARY_FIGURES]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


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
