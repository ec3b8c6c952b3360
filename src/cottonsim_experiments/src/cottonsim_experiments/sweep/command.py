"""``reproduce sweep``: read a sweep file, check every run, run them on Ray, write the tables."""
from __future__ import annotations

import os
from typing import Optional

from cottonsim_common.config.yaml_files import load_yaml_file

from .engine import EngineConfig, print_flush, run_sweep
from .route_runs import execute_route_run, validate_route_run
from .spec import parse_sweep


def sweep_command(config_path: str, results_dir: str, address: Optional[str] = None, cpus_per_run: int = 2,
                  max_retries: int = 2, resume: bool = False, local_cpus: Optional[int] = None) -> int:
    """Run the sweep of ``config_path`` into RESULTS/sweeps/<name>/; 0 when every run has a report."""
    if not os.path.isfile(config_path):
        raise ValueError(f"--config {config_path!r}: no such sweep file")
    data = load_yaml_file(config_path, default=None)
    default_name = os.path.splitext(os.path.basename(config_path))[0]
    spec = parse_sweep(data, default_name=default_name)
    if spec.waypoints and not os.path.isabs(spec.waypoints):
        # a route file named in the sweep file is relative to the sweep file
        from dataclasses import replace
        spec = replace(spec, waypoints=os.path.join(os.path.dirname(os.path.abspath(config_path)), spec.waypoints))
    config = EngineConfig(address=address, cpus_per_run=cpus_per_run, max_retries=max_retries, resume=resume,
                          local_cpus=local_cpus)
    sweep_dir = os.path.join(results_dir, "sweeps", spec.name)
    result = run_sweep(spec, sweep_dir, config, execute_route_run, validate=validate_route_run,
                       sweep_file=config_path, log=print_flush)
    counts = result["counts"]
    print_flush(f"runs.csv: {result['runs_csv']}\nsummary:  {result['summary_md']}")
    return 0 if counts.get("failed", 0) == 0 else 1
