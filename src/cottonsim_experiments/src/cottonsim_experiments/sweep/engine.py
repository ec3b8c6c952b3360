"""Run a sweep's runs as Ray tasks: a local cluster by default, any Ray cluster with an address.

Each run is one task that reserves ``cpus_per_run`` cores (a bringup starved of cores slows its own
sim time) and returns its outcome; the driver writes every outcome as it arrives
(:mod:`.records`), so a sweep stopped at any point keeps its finished runs. Retries are the
driver's, so they are counted: a task whose worker or node dies, or whose master port was taken,
is submitted again (Ray places it where cores are free) up to ``max_retries`` times; any other
failure is the run's own result and is not retried. Ctrl-C cancels the running tasks (each stops
its bringup with SIGINT, so the recorder writes what it has) and ends the sweep.
"""
from __future__ import annotations

import os
import shutil
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Optional

from .records import STATUS_DONE, STATUS_FAILED, Progress, finished_run_ids, write_run, write_tables
from .spec import RunSpec, SweepConfigError, SweepSpec, check_runs

RunFunction = Callable[[RunSpec, int], Dict[str, Any]]


@dataclass(frozen=True)
class EngineConfig:
    """How a sweep runs: the cluster, the cores per run, the retries."""

    address: Optional[str] = None        # None: start a local cluster; "auto" or "HOST:PORT": join one
    cpus_per_run: int = 2                # cores each run reserves (and its NUMBA/OMP thread count)
    local_cpus: Optional[int] = None     # a local cluster's cores (default: this machine's)
    max_retries: int = 2                 # extra attempts after a worker/node death or a taken master port
    resume: bool = False                 # skip runs whose folder says done
    progress_interval_s: float = 10.0    # how often the progress line is printed while nothing finishes
    cancel_grace_s: float = 60.0         # Ctrl-C: how long running bringups get to stop cleanly

    def __post_init__(self) -> None:
        if int(self.cpus_per_run) < 1:
            raise ValueError(f"cpus_per_run must be >= 1, got {self.cpus_per_run!r}")
        if self.local_cpus is not None and int(self.local_cpus) < 1:
            raise ValueError(f"local_cpus must be >= 1, got {self.local_cpus!r}")
        if int(self.max_retries) < 0:
            raise ValueError(f"max_retries must be >= 0, got {self.max_retries!r}")
        if not self.progress_interval_s > 0.0:
            raise ValueError(f"progress_interval_s must be > 0 s, got {self.progress_interval_s!r}")


def _task_body(run_function: RunFunction, run: RunSpec, cpus: int) -> Dict[str, Any]:
    """What runs inside the Ray task: the run function, with the node it ran on."""
    import ray

    outcome = dict(run_function(run, cpus))
    outcome.setdefault("node", os.uname().nodename)
    outcome["node_ip"] = ray.util.get_node_ip_address()
    outcome["ray_node"] = ray.get_runtime_context().get_node_id()[:12]
    return outcome


def _retryable(exc: BaseException) -> bool:
    """Failures that say nothing about the run itself: its worker or node died, its master port was taken."""
    import ray.exceptions as rex

    from .route_runs import MasterPortTaken

    if isinstance(exc, (rex.WorkerCrashedError, rex.NodeDiedError, rex.ObjectLostError,
                        rex.LocalRayletDiedError)):
        return True
    if isinstance(exc, rex.RayTaskError):
        cause = getattr(exc, "cause", None)
        return isinstance(cause, MasterPortTaken) or "MasterPortTaken" in str(exc)
    return False


def _failure_outcome(exc: BaseException, attempts: int) -> Dict[str, Any]:
    text = str(exc).strip().splitlines()
    return {"status": STATUS_FAILED, "error": f"{type(exc).__name__}: {text[-1] if text else ''}"[:500],
            "attempts": attempts, "files": {}}


def prepare_sweep_dir(spec: SweepSpec, runs: List[RunSpec], sweep_dir: str, sweep_file: Optional[str],
                      resume: bool) -> List[str]:
    """Create the sweep folder; the ids of finished runs to skip. Refuses to mix a new sweep into an old one."""
    finished = finished_run_ids(sweep_dir, runs) if os.path.isdir(sweep_dir) else []
    if finished and not resume:
        raise SweepConfigError(f"{sweep_dir} already holds {len(finished)} finished runs of this sweep: give "
                               "--resume to keep them and run the rest, or another sweep name")
    os.makedirs(os.path.join(sweep_dir, "runs"), exist_ok=True)
    if sweep_file:
        shutil.copyfile(sweep_file, os.path.join(sweep_dir, "sweep.yaml"))
    return finished


def run_sweep(spec: SweepSpec, sweep_dir: str, config: EngineConfig, run_function: RunFunction,
              validate: Optional[Callable[[RunSpec], None]] = None, sweep_file: Optional[str] = None,
              log: Callable[[str], None] = print) -> Dict[str, Any]:
    """Run every run of ``spec`` not yet done; returns the counts and the paths of runs.csv and summary.md."""
    import ray

    runs = spec.runs()
    if validate is not None:
        check_runs(runs, validate)
    skip = set(prepare_sweep_dir(spec, runs, sweep_dir, sweep_file, config.resume))
    todo = [r for r in runs if r.run_id not in skip]
    progress = Progress(total=len(runs), skipped=len(skip))
    log(f"[sweep {spec.name}] {len(runs)} runs ({len(skip)} done before, {len(todo)} to run) -> {sweep_dir}")
    if not todo:
        return dict(counts=progress.__dict__, **write_tables(sweep_dir, runs))

    started_here = not ray.is_initialized()
    if started_here:
        if config.address:
            ray.init(address=config.address, log_to_driver=False, include_dashboard=False)
        else:
            ray.init(num_cpus=config.local_cpus or os.cpu_count(), log_to_driver=False, include_dashboard=False)
    cluster_cpus = int(ray.cluster_resources().get("CPU", 0))
    if cluster_cpus < config.cpus_per_run:
        raise SweepConfigError(f"the cluster has {cluster_cpus} CPUs, fewer than --cpus-per-run "
                               f"{config.cpus_per_run}: no run could ever start")
    slots = max(1, cluster_cpus // config.cpus_per_run)
    remote = ray.remote(_task_body).options(num_cpus=config.cpus_per_run, max_retries=0)
    pending: Dict[Any, tuple] = {}

    def submit(run: RunSpec, attempt: int) -> None:
        pending[remote.remote(run_function, run, config.cpus_per_run)] = (run, attempt, time.monotonic())

    for run in todo:
        submit(run, 1)
    log(f"[sweep {spec.name}] cluster: {cluster_cpus} CPUs, {config.cpus_per_run} per run -> {slots} at a time")
    try:
        last_line = 0.0
        while pending:
            progress.running = min(len(pending), slots)
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=config.progress_interval_s)
            for ref in ready:
                run, attempt, submitted = pending.pop(ref)
                try:
                    outcome = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - sorted into retry / failure below
                    if _retryable(exc) and attempt <= config.max_retries:
                        progress.retries += 1
                        log(f"[sweep {spec.name}] {run.run_id}: attempt {attempt} lost ({type(exc).__name__}); "
                            "running it again")
                        submit(run, attempt + 1)
                        continue
                    outcome = _failure_outcome(exc, attempt)
                outcome["attempts"] = attempt
                write_run(sweep_dir, run, outcome)
                if outcome.get("status") == STATUS_DONE:
                    progress.done += 1
                    progress.wall_s.append(float(outcome.get("wall_s", time.monotonic() - submitted)))
                else:
                    progress.failed += 1
                write_tables(sweep_dir, runs)
                log(f"[sweep {spec.name}] {run.run_id}: {outcome.get('status')} on {outcome.get('node', '?')}"
                    + (f" ({outcome.get('error')})" if outcome.get("error") else ""))
            if ready or time.monotonic() - last_line >= config.progress_interval_s:
                progress.running = min(len(pending), slots)
                log(f"[sweep {spec.name}] {progress.line(slots)}")
                last_line = time.monotonic()
    except KeyboardInterrupt:
        log(f"[sweep {spec.name}] interrupted: stopping {len(pending)} runs (finished runs are kept)")
        for ref in list(pending):
            ray.cancel(ref, force=False)
        ray.wait(list(pending), num_returns=len(pending), timeout=config.cancel_grace_s)
        write_tables(sweep_dir, runs)
        if started_here:
            ray.shutdown()
        raise
    tables = write_tables(sweep_dir, runs)
    if started_here:
        ray.shutdown()
    progress.running = 0
    log(f"[sweep {spec.name}] finished: {progress.line(slots)}; {tables['runs_csv']}")
    return dict(counts={k: v for k, v in progress.__dict__.items() if k != "wall_s"}, **tables)


def print_flush(text: str) -> None:
    sys.stdout.write(text + "\n")
    sys.stdout.flush()
