"""A sweep: a grid of experiment runs read from YAML and expanded into runs with stable ids.

A sweep file names one experiment, its seeds and a grid of overrides; every combination of the
grid's values with every seed is one run, one bringup::

    name: gps_noise                 # folder results/sweeps/<name>/
    experiment: gps_route           # gps_route | map_route
    seeds: [0, 1, 2]                # default [0]
    grid:                           # each key a list of values; the runs are their product x seeds
      sim.gps.noise_std_m: [0.01, 0.05]     # sim.<key>: a simulator setting (dotted path into sim_navigation.yaml)
      launch.vision: [false]                # launch.<arg>: an argument of the experiment's launch file
    fixed:                          # the same for every run (not part of the run ids)
      sim.farm.rows: 5
    waypoints: null                 # a route file instead of the experiment's own
    real_time_factor: 0             # 0 = as fast as possible
    record_bag: false
    wall_timeout_s: 5400            # per run [s]

Nothing here imports ROS or Ray: the file is parsed and checked (unknown keys, wrong types,
empty lists) before anything starts, and the simulator settings of every run are checked by the
experiment's own validator (:class:`RunValidator`), so a misspelt key fails in the driver with
its name, not an hour later in a bringup.
"""
from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

EXPERIMENTS = ("gps_route", "map_route")
TOP_LEVEL_KEYS = ("name", "experiment", "seeds", "grid", "fixed", "waypoints", "real_time_factor", "record_bag",
                  "wall_timeout_s")
OVERRIDE_SCOPES = ("sim", "launch")
# Launch arguments a sweep sets itself for every run: a grid may not override them.
RESERVED_LAUNCH_ARGS = ("run_name", "results_dir", "sim_config", "waypoints", "real_time_factor", "record_bag")
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


class SweepConfigError(ValueError):
    """A sweep file that cannot be run; the message names the key and what is wrong with it."""


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: an experiment, a seed and the overrides of its grid point."""

    run_id: str
    experiment: str
    seed: int
    sim_overrides: Mapping[str, Any]            # nested mapping merged into the experiment's sim settings
    launch_args: Mapping[str, Any]              # extra launch arguments
    parameters: Mapping[str, Any]               # the grid point: dotted key -> value (for tables)
    waypoints: Optional[str] = None
    real_time_factor: float = 0.0
    record_bag: bool = False
    wall_timeout_s: float = 5400.0


@dataclass(frozen=True)
class SweepSpec:
    """A parsed, checked sweep file."""

    name: str
    experiment: str
    seeds: Tuple[int, ...] = (0,)
    grid: Mapping[str, Tuple[Any, ...]] = field(default_factory=dict)
    fixed: Mapping[str, Any] = field(default_factory=dict)
    waypoints: Optional[str] = None
    real_time_factor: float = 0.0
    record_bag: bool = False
    wall_timeout_s: float = 5400.0

    def runs(self) -> List[RunSpec]:
        """Every run: the product of the grid's values, times the seeds, in a fixed order."""
        keys = list(self.grid)
        points = [dict(zip(keys, values)) for values in itertools.product(*(self.grid[k] for k in keys))] or [{}]
        out = []
        for point in points:
            for seed in self.seeds:
                sim, launch = _split_scopes({**self.fixed, **point})
                out.append(RunSpec(run_id=run_id(seed, point), experiment=self.experiment, seed=seed,
                                   sim_overrides=sim, launch_args=launch, parameters=dict(point),
                                   waypoints=self.waypoints, real_time_factor=self.real_time_factor,
                                   record_bag=self.record_bag, wall_timeout_s=self.wall_timeout_s))
        ids = [r.run_id for r in out]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:
            raise SweepConfigError(f"grid values give the same run id twice ({duplicates[0]!r}): make the values "
                                   "differ in their text")
        return out


@dataclass(frozen=True)
class RunList:
    """Runs built in code (the ``reproduce`` experiments), run by the engine like a sweep file's runs."""

    name: str
    run_list: Tuple[RunSpec, ...]

    def runs(self) -> List[RunSpec]:
        ids = [r.run_id for r in self.run_list]
        if len(set(ids)) != len(ids):
            raise SweepConfigError(f"{self.name}: a run id appears twice ({sorted(ids)})")
        return list(self.run_list)


def _value_text(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:g}"
    text = str(value)
    return re.sub(r"[^A-Za-z0-9_.+-]+", "_", text).strip("_") or "_"


def run_id(seed: int, parameters: Mapping[str, Any]) -> str:
    """A readable, filesystem-safe id: ``seed_0`` or ``seed_0__gps.noise_std_m=0.05__vision=false``."""
    parts = [f"seed_{seed}"]
    for key in parameters:            # in the order of the sweep file's grid
        short = key.split(".", 1)[1] if "." in key else key
        parts.append(f"{_value_text(short)}={_value_text(parameters[key])}")
    return "__".join(parts)


def _split_scopes(flat: Mapping[str, Any]) -> Tuple[Dict[str, Any], Dict[str, Any]]:
    """Dotted ``sim.a.b`` / ``launch.x`` keys -> (nested sim overrides, launch arguments)."""
    sim: Dict[str, Any] = {}
    launch: Dict[str, Any] = {}
    for key, value in flat.items():
        scope, rest = key.split(".", 1)
        if scope == "launch":
            launch[rest] = value
            continue
        node = sim
        parts = rest.split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return sim, launch


def _check_key(key: Any, where: str) -> str:
    if not isinstance(key, str) or "." not in key:
        raise SweepConfigError(f"{where}: key {key!r} must be 'sim.<setting>' or 'launch.<argument>'")
    scope, rest = key.split(".", 1)
    if scope not in OVERRIDE_SCOPES:
        raise SweepConfigError(f"{where}: key {key!r} starts with {scope!r}; it must start with "
                               + " or ".join(repr(s + ".") for s in OVERRIDE_SCOPES))
    if not rest or any(not part for part in rest.split(".")):
        raise SweepConfigError(f"{where}: key {key!r} has an empty part")
    if scope == "launch" and rest in RESERVED_LAUNCH_ARGS:
        raise SweepConfigError(f"{where}: key {key!r}: the sweep sets launch argument {rest!r} itself "
                               "(use the sweep file's own key where there is one)")
    return key


def _scalar(value: Any, where: str) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        raise SweepConfigError(f"{where}: {value!r} is not a finite number")
    if value is not None and not isinstance(value, (bool, int, float, str)):
        raise SweepConfigError(f"{where}: {value!r} must be a number, a string or a boolean")
    return value


def _flatten_fixed(fixed: Mapping, prefix: str = "") -> Dict[str, Any]:
    """``fixed`` given nested ({sim: {farm: {rows: 5}}}) or dotted ({sim.farm.rows: 5}) -> dotted keys."""
    out: Dict[str, Any] = {}
    for key, value in fixed.items():
        if not isinstance(key, str):
            raise SweepConfigError(f"fixed: key {key!r} must be a string")
        dotted = f"{prefix}.{key}" if prefix else key
        if isinstance(value, Mapping):
            out.update(_flatten_fixed(value, dotted))
        else:
            out[dotted] = value
    return out


def parse_sweep(data: Any, default_name: str = "sweep") -> SweepSpec:
    """A :class:`SweepSpec` from a sweep file's mapping; :class:`SweepConfigError` naming the bad key."""
    if not isinstance(data, Mapping):
        raise SweepConfigError("a sweep file must be a YAML mapping (name, experiment, seeds, grid, ...)")
    unknown = sorted(str(k) for k in data if k not in TOP_LEVEL_KEYS)
    if unknown:
        raise SweepConfigError(f"unknown key {unknown[0]!r}; a sweep file knows " + ", ".join(TOP_LEVEL_KEYS))
    name = data.get("name", default_name)
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise SweepConfigError(f"name: {name!r} must be letters, digits, '_', '-' or '.' (it names a folder)")
    experiment = data.get("experiment")
    if experiment not in EXPERIMENTS:
        raise SweepConfigError(f"experiment: {experiment!r} must be one of {', '.join(EXPERIMENTS)}")
    seeds = data.get("seeds", [0])
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        seeds = [seeds]
    if (not isinstance(seeds, list) or not seeds
            or any(not isinstance(s, int) or isinstance(s, bool) or s < 0 for s in seeds)):
        raise SweepConfigError(f"seeds: {seeds!r} must be a non-empty list of integers >= 0")
    if len(set(seeds)) != len(seeds):
        raise SweepConfigError(f"seeds: {seeds!r} names a seed twice")
    grid_in = data.get("grid") or {}
    if not isinstance(grid_in, Mapping):
        raise SweepConfigError("grid: must be a mapping of 'sim.<setting>' / 'launch.<argument>' to lists")
    grid: Dict[str, Tuple[Any, ...]] = {}
    for key, values in grid_in.items():
        _check_key(key, "grid")
        if not isinstance(values, list) or not values:
            raise SweepConfigError(f"grid: {key!r} must be a non-empty list of values, got {values!r}")
        grid[key] = tuple(_scalar(v, f"grid: {key!r}") for v in values)
    fixed_in = data.get("fixed") or {}
    if not isinstance(fixed_in, Mapping):
        raise SweepConfigError("fixed: must be a mapping of 'sim.<setting>' / 'launch.<argument>' to values")
    fixed = {}
    for key, value in _flatten_fixed(fixed_in).items():
        _check_key(key, "fixed")
        if key in grid:
            raise SweepConfigError(f"fixed: {key!r} is also a grid key")
        fixed[key] = _scalar(value, f"fixed: {key!r}")
    waypoints = data.get("waypoints")
    if waypoints is not None and not isinstance(waypoints, str):
        raise SweepConfigError(f"waypoints: {waypoints!r} must be a file path or null")
    rtf = data.get("real_time_factor", 0.0)
    if isinstance(rtf, bool) or not isinstance(rtf, (int, float)) or not (math.isfinite(rtf) and rtf >= 0.0):
        raise SweepConfigError(f"real_time_factor: {rtf!r} must be a number >= 0 (0: as fast as possible)")
    record_bag = data.get("record_bag", False)
    if not isinstance(record_bag, bool):
        raise SweepConfigError(f"record_bag: {record_bag!r} must be true or false")
    wall = data.get("wall_timeout_s", 5400.0)
    if isinstance(wall, bool) or not isinstance(wall, (int, float)) or not (math.isfinite(wall) and wall > 0.0):
        raise SweepConfigError(f"wall_timeout_s: {wall!r} must be a number of seconds > 0")
    return SweepSpec(name=name, experiment=experiment, seeds=tuple(int(s) for s in seeds), grid=grid, fixed=fixed,
                     waypoints=waypoints, real_time_factor=float(rtf), record_bag=record_bag,
                     wall_timeout_s=float(wall))


RunValidator = Callable[[RunSpec], None]


def check_runs(runs: Sequence[RunSpec], validate: RunValidator) -> None:
    """Run ``validate`` on every run; the first failure becomes a :class:`SweepConfigError` naming the run."""
    for run in runs:
        try:
            validate(run)
        except (TypeError, ValueError) as exc:
            raise SweepConfigError(f"run {run.run_id}: {exc}") from exc
