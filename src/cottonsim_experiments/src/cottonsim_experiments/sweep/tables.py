"""A sweep's tables: runs.csv (one row per run) and summary.md (the spread of each figure per grid point).

Written incrementally, so a sweep of N runs costs O(N) in writing, not O(N^2): runs.csv gets one
appended row as each run's outcome reaches the driver; summary.md is rewritten from the rows held
in memory every ``summary_every_runs`` outcomes or ``summary_every_s`` seconds, whichever comes
first; at the end (or on Ctrl-C) :meth:`SweepTables.finish` writes both once more, runs.csv then
in the sweep's run order with the runs that never finished listed as ``missing``. Nothing here
imports Ray or ROS.
"""
from __future__ import annotations

import csv
import math
import os
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence

from ..reproduce.seeds import aggregate_reports, format_spread
from .records import STATUS_DONE, STATUS_FAILED, read_outcome, read_run_report
from .spec import RunSpec

# The report's figures copied into runs.csv and summarised in summary.md.
FIGURES = ("complete", "cr_percent", "cr_percent_010m", "ae_m", "rmse_m", "cross_track_mean_m", "cross_track_max_m",
           "plant_contacts", "sim_duration_s", "real_time_factor")
RUN_COLUMNS = ("run_id", "seed", "status", "attempts", "node", "ray_node", "load_average_1m", "wall_s", "error")
STATUS_MISSING = "missing"
# (figure, column title, scale, digits) of summary.md
_SUMMARY_FIGURES = (("cr_percent", "CR 5e-6 deg [%]", 1.0, 1), ("cr_percent_010m", "CR 0.10 m [%]", 1.0, 1),
                    ("ae_m", "AE [m]", 1.0, 3), ("rmse_m", "RMSE [m]", 1.0, 3),
                    ("cross_track_mean_m", "in-row cross-track mean [cm]", 100.0, 2),
                    ("plant_contacts", "plant contacts", 1.0, 1), ("sim_duration_s", "route [min]", 1 / 60, 2),
                    ("real_time_factor", "RTF", 1.0, 2))


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.6g}"
    return "" if value is None else value


class SweepTables:
    """runs.csv and summary.md of one sweep, kept up to date as outcomes arrive (see the module's text)."""

    def __init__(self, sweep_dir: str, runs: Sequence[RunSpec], runs_dir: Optional[str] = None,
                 summary_every_runs: int = 10, summary_every_s: float = 60.0,
                 clock: Callable[[], float] = time.monotonic):
        if int(summary_every_runs) < 1:
            raise ValueError(f"summary_every_runs must be >= 1, got {summary_every_runs!r}")
        if not summary_every_s > 0.0:
            raise ValueError(f"summary_every_s must be > 0 s, got {summary_every_s!r}")
        self.sweep_dir = sweep_dir
        self.runs_dir = runs_dir or os.path.join(sweep_dir, "runs")
        self.runs = list(runs)
        self.parameter_keys = sorted({k for r in self.runs for k in r.parameters})
        self.columns = ["run_id", "seed", *self.parameter_keys, *RUN_COLUMNS[2:], *FIGURES]
        self.runs_csv = os.path.join(sweep_dir, "runs.csv")
        self.summary_md = os.path.join(sweep_dir, "summary.md")
        self.summary_every_runs = int(summary_every_runs)
        self.summary_every_s = float(summary_every_s)
        self._clock = clock
        self._status: Dict[str, str] = {}
        self._reports: Dict[str, Dict[str, Any]] = {}
        self._rows: Dict[str, Dict[str, Any]] = {}
        self._since_summary = 0
        self._summary_at = clock()
        self.summaries_written = 0

    def paths(self) -> Dict[str, str]:
        return {"runs_csv": self.runs_csv, "summary_md": self.summary_md}

    def _row(self, run: RunSpec, outcome: Mapping[str, Any], report: Optional[Mapping[str, Any]]) -> Dict[str, Any]:
        row: Dict[str, Any] = {"run_id": run.run_id, "seed": run.seed}
        row.update({k: run.parameters.get(k) for k in self.parameter_keys})
        row.update({k: outcome.get(k) for k in RUN_COLUMNS if k not in ("run_id", "seed")})
        row.update({k: (report or {}).get(k) for k in FIGURES})
        return {k: _cell(row.get(k)) for k in self.columns}

    def _remember(self, run: RunSpec, outcome: Mapping[str, Any], report: Optional[Mapping[str, Any]]) -> None:
        self._status[run.run_id] = str(outcome.get("status", STATUS_MISSING))
        self._rows[run.run_id] = self._row(run, outcome, report)
        if report is not None:
            self._reports[run.run_id] = dict(report)
        else:
            self._reports.pop(run.run_id, None)

    def _load(self, run: RunSpec) -> Dict[str, Any]:
        """A run's row from its folder (runs finished before this driver started)."""
        outcome = read_outcome(self.runs_dir, run.run_id) or {"status": STATUS_MISSING}
        report = read_run_report(self.runs_dir, run.run_id)
        self._remember(run, outcome, report)
        return self._rows[run.run_id]

    def start(self, finished_ids: Sequence[str] = ()) -> None:
        """runs.csv with its header and the rows of the runs finished before (read from their folders once)."""
        os.makedirs(self.sweep_dir, exist_ok=True)
        wanted = set(finished_ids)
        with open(self.runs_csv, "w", encoding="utf-8", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=self.columns)
            writer.writeheader()
            for run in self.runs:
                if run.run_id in wanted:
                    writer.writerow(self._load(run))

    def add(self, run: RunSpec, outcome: Mapping[str, Any], report: Optional[Mapping[str, Any]]) -> None:
        """One finished run: its row appended to runs.csv; summary.md rewritten when it is due."""
        self._remember(run, outcome, report)
        with open(self.runs_csv, "a", encoding="utf-8", newline="") as fh:
            csv.DictWriter(fh, fieldnames=self.columns).writerow(self._rows[run.run_id])
        self._since_summary += 1
        if (self._since_summary >= self.summary_every_runs
                or self._clock() - self._summary_at >= self.summary_every_s):
            self.write_summary()

    def write_summary(self) -> None:
        with open(self.summary_md, "w", encoding="utf-8") as fh:
            fh.write(self.summary_markdown() + "\n")
        self._since_summary = 0
        self._summary_at = self._clock()
        self.summaries_written += 1

    def finish(self) -> Dict[str, str]:
        """Both tables once more, runs.csv in run order (runs not finished read from their folders, or 'missing')."""
        with open(self.runs_csv, "w", encoding="utf-8", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=self.columns)
            writer.writeheader()
            for run in self.runs:
                writer.writerow(self._rows.get(run.run_id) or self._load(run))
        self.write_summary()
        return self.paths()

    def summary_markdown(self) -> str:
        """One row per grid point: the spread of each figure over its seeds ('mean ± std (min..max, n)')."""
        groups: Dict[tuple, List[RunSpec]] = {}
        for run in self.runs:
            groups.setdefault(tuple(run.parameters.get(k) for k in self.parameter_keys), []).append(run)
        status = [self._status.get(r.run_id, STATUS_MISSING) for r in self.runs]
        missing = len(status) - status.count(STATUS_DONE) - status.count(STATUS_FAILED)
        lines = [f"# Sweep {os.path.basename(os.path.normpath(self.sweep_dir))}", "",
                 f"{len(self.runs)} runs: {status.count(STATUS_DONE)} done, {status.count(STATUS_FAILED)} failed, "
                 f"{missing} not run. Each cell: mean ± std (min..max, n) over the seeds.", ""]
        header = [*self.parameter_keys, "runs with a report", *(title for _, title, _, _ in _SUMMARY_FIGURES)]
        lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        for key, members in groups.items():
            reports = [self._reports[r.run_id] for r in members if r.run_id in self._reports]
            stats = aggregate_reports(reports, [f for f, _, _, _ in _SUMMARY_FIGURES])
            cells = [str(v) for v in key] + [f"{len(reports)}/{len(members)}"]
            cells += [format_spread(stats.get(f, {}), scale, digits) for f, _, scale, digits in _SUMMARY_FIGURES]
            lines.append("| " + " | ".join(cells) + " |")
        return "\n".join(lines)


def write_tables(sweep_dir: str, runs: Sequence[RunSpec], runs_dir: Optional[str] = None) -> Dict[str, str]:
    """runs.csv and summary.md from the run folders alone (runs without an outcome listed as 'missing')."""
    tables = SweepTables(sweep_dir, runs, runs_dir)
    tables.start()
    return tables.finish()
