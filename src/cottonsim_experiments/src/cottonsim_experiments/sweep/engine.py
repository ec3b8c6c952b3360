"""Run a sweep's runs as Ray tasks: a local cluster by default, any Ray cluster with an address.

Each run is one task that reserves ``cpus_per_run`` cores (a bringup starved of cores slows its own
sim time) and returns its outcome; the driver writes every outcome as it arrives (its folder,
:mod:`.records`; a row appended to runs.csv, :mod:`.tables`), so a sweep stopped at any point keeps
its finished runs. Retries are the driver's, so they are counted: a task whose worker or node
dies, or whose master port was taken, is submitted again (Ray places it where cores are free) up
to ``max_retries`` times; any other failure is the run's own result and is not retried. Ctrl-C
cancels the running tasks (each stops its bringup with SIGINT, so the recorder writes what it has),
records the runs that finished before their cancel arrived, and ends the sweep.
"""
from __future__ import annotations

import os
import shutil
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Optional

from .records import STATUS_DONE, STATUS_FAILED, Progress, finished_run_ids, outcome_report, write_run
from .spec import RunSpec, SweepConfigError, SweepSpec, check_runs
from .tables import SweepTables

RunFunction = Callable[[RunSpec, int], Dict[str, Any]]


@dataclass(frozen=True)
class EngineConfig:
    """How a sweep runs: the cluster, the cores per run, the retries."""

    address: Optional[str] = None        # None: start a local cluster; "auto" or "HOST:PORT": join one
    cpus_per_run: int = 2                # cores each run reserves (and its NUMBA/OMP thread count)
    local_cpus: Optional[int] = None     # a local cluster's cores (default: this machine's)
    max_retries: int = 2                 # extra attempts after a worker/node death or a taken master port
    resume: bool = False                 # skip runs whose folder says done
    replace_finished: bool = False       # without resume: run finished runs again, replacing their folders
    progress_interval_s: float = 10.0    # how often the progress line is printed while nothing finishes
    cancel_grace_s: float = 60.0         # Ctrl-C: how long running bringups get to stop cleanly
    summary_every_runs: int = 10         # summary.md rewritten after this many outcomes ...
    summary_every_s: float = 60.0        # ... or this long after the last rewrite, and at the end

    def __post_init__(self) -> None:
        if int(self.cpus_per_run) < 1:
            raise ValueError(f"cpus_per_run must be >= 1, got {self.cpus_per_run!r}")
        if self.local_cpus is not None and int(self.local_cpus) < 1:
            raise ValueError(f"local_cpus must be >= 1, got {self.local_cpus!r}")
        if int(self.max_retries) < 0:
            raise ValueError(f"max_retries must be >= 0, got {self.max_retries!r}")
        if int(self.summary_every_runs) < 1:
            raise ValueError(f"summary_every_runs must be >= 1, got {self.summary_every_runs!r}")
        if not self.summary_every_s > 0.0:
            raise ValueError(f"summary_every_s must be > 0 s, got {self.summary_every_s!r}")
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


def prepare_sweep_dir(runs: List[RunSpec], sweep_dir: str, runs_dir: str, sweep_file: Optional[str],
                      config: EngineConfig) -> List[str]:
    """Create the sweep folder; the ids of finished runs to skip. Refuses to mix a new sweep into an old one."""
    finished = finished_run_ids(runs_dir, runs) if os.path.isdir(runs_dir) else []
    if finished and not (config.resume or config.replace_finished):
        raise SweepConfigError(f"{sweep_dir} already holds {len(finished)} finished runs of this sweep: give "
                               "--resume to keep them and run the rest, or another sweep name")
    os.makedirs(runs_dir, exist_ok=True)
    if sweep_file:
        shutil.copyfile(sweep_file, os.path.join(sweep_dir, "sweep.yaml"))
    return finished if config.resume else []


def _start_ray(config: EngineConfig) -> bool:
    """Connect to the cluster (or start a local one); True when this call started Ray (and must stop it)."""
    import ray

    if ray.is_initialized():
        return False
    if config.address:
        ray.init(address=config.address, log_to_driver=False, include_dashboard=False)
    else:
        ray.init(num_cpus=config.local_cpus or os.cpu_count(), log_to_driver=False, include_dashboard=False)
    return True


def run_sweep(spec: SweepSpec, sweep_dir: str, config: EngineConfig, run_function: RunFunction,
              validate: Optional[Callable[[RunSpec], None]] = None, sweep_file: Optional[str] = None,
              log: Callable[[str], None] = print, runs_dir: Optional[str] = None) -> Dict[str, Any]:
    """Run every run of ``spec`` not yet done; returns the counts and the paths of runs.csv and summary.md.

    ``spec``: anything with a ``name`` and ``runs()`` (a parsed sweep file, or a :class:`RunList`
    built in code); ``runs_dir``: where the run folders go (default ``sweep_dir/runs``).
    """
    import ray

    runs = spec.runs()
    runs_dir = runs_dir or os.path.join(sweep_dir, "runs")
    if validate is not None:
        check_runs(runs, validate)
    skip = set(prepare_sweep_dir(runs, sweep_dir, runs_dir, sweep_file, config))
    todo = [r for r in runs if r.run_id not in skip]
    progress = Progress(total=len(runs), skipped=len(skip))
    tables = SweepTables(sweep_dir, runs, runs_dir, config.summary_every_runs, config.summary_every_s)
    tables.start(sorted(skip))
    log(f"[sweep {spec.name}] {len(runs)} runs ({len(skip)} done before, {len(todo)} to run) -> {sweep_dir}")
    if not todo:
        return dict(counts=progress.counts(), **tables.finish())

    started_here = _start_ray(config)
    cluster_cpus = int(ray.cluster_resources().get("CPU", 0))
    if cluster_cpus < config.cpus_per_run:
        if started_here:
            ray.shutdown()
        raise SweepConfigError(f"the cluster has {cluster_cpus} CPUs, fewer than --cpus-per-run "
                               f"{config.cpus_per_run}: no run could ever start")
    slots = max(1, cluster_cpus // config.cpus_per_run)
    remote = ray.remote(_task_body).options(num_cpus=config.cpus_per_run, max_retries=0)
    pending: Dict[Any, tuple] = {}

    def submit(run: RunSpec, attempt: int) -> None:
        pending[remote.remote(run_function, run, config.cpus_per_run)] = (run, attempt, time.monotonic())

    def record(run: RunSpec, attempt: int, submitted: float, outcome: Dict[str, Any]) -> None:
        outcome["attempts"] = attempt
        write_run(runs_dir, run, outcome)
        tables.add(run, outcome, outcome_report(outcome))
        if outcome.get("status") == STATUS_DONE:
            progress.done += 1
            progress.wall_s.append(float(outcome.get("wall_s", time.monotonic() - submitted)))
        else:
            progress.failed += 1
        log(f"[sweep {spec.name}] {run.run_id}: {outcome.get('status')} on {outcome.get('node', '?')}"
            + (f" ({outcome.get('error')})" if outcome.get("error") else ""))

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
                record(run, attempt, submitted, outcome)
            if ready or time.monotonic() - last_line >= config.progress_interval_s:
                progress.running = min(len(pending), slots)
                log(f"[sweep {spec.name}] {progress.line(slots)}")
                last_line = time.monotonic()
    except KeyboardInterrupt:
        log(f"[sweep {spec.name}] interrupted: stopping {len(pending)} runs (finished runs are kept)")
        _cancel(pending, config.cancel_grace_s, record)
        tables.finish()
        if started_here:
            ray.shutdown()
        raise
    paths = tables.finish()
    if started_here:
        ray.shutdown()
    progress.running = 0
    log(f"[sweep {spec.name}] finished: {progress.line(slots)}; {paths['runs_csv']}")
    return dict(counts=progress.counts(), **paths)


def _cancel(pending: Dict[Any, tuple], grace_s: float, record: Callable) -> None:
    """Ctrl-C: cancel every pending task (each stops its bringup with SIGINT), wait up to ``grace_s`` for
    them to end, and record the runs that finished before their cancel arrived."""
    import ray

    for ref in list(pending):
        ray.cancel(ref, force=False)
    ended, _ = ray.wait(list(pending), num_returns=len(pending), timeout=grace_s)
    for ref in ended:
        run, attempt, submitted = pending.pop(ref)
        try:
            outcome = ray.get(ref, timeout=0)
        except Exception:  # noqa: BLE001 - a cancelled run is simply not finished
            continue
        if outcome.get("status") == STATUS_DONE:
            record(run, attempt, submitted, outcome)


def print_flush(text: str) -> None:
    sys.stdout.write(text + "\n")
    sys.stdout.flush()
