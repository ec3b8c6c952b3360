"""Build the simulator's nested config dataclasses from plain dicts (YAML, rosparam).

The config dataclasses hold the defaults; a YAML file or the ROS parameter
server only lists what differs. ``apply_mapping`` walks a dataclass and a
mapping together, so a misspelt key is an error naming its full path
(``lidar.samples_per_rings``) instead of a silently ignored setting, and each
dataclass still validates its own values in ``__post_init__``.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Mapping

from cottonsim_world.faults.schedule import fault_schedule_from_list
from cottonsim_world.sensors.camera import CameraConfig


def _convert(value: Any, default: Any, path: str) -> Any:
    if dataclasses.is_dataclass(default) and not isinstance(default, type):
        if not isinstance(value, Mapping):
            raise ValueError(f"config key '{path}' must be a mapping, got {value!r}")
        return apply_mapping(default, value, path)
    if isinstance(default, tuple) and isinstance(value, (list, tuple)):
        return tuple(value)
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ValueError(f"config key '{path}' must be true or false, got {value!r}")
        return value
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def apply_mapping(instance: Any, mapping: Mapping[str, Any], path: str = "") -> Any:
    """A copy of dataclass ``instance`` with the values of ``mapping`` applied (recursively)."""
    fields = {f.name: f for f in dataclasses.fields(instance)}
    changes = {}
    for key, value in mapping.items():
        full = f"{path}.{key}" if path else str(key)
        if key not in fields:
            raise ValueError(f"unknown config key '{full}' (known here: {', '.join(sorted(fields))})")
        changes[key] = _convert(value, getattr(instance, key), full)
    try:
        return dataclasses.replace(instance, **changes)
    except TypeError as exc:      # a wrong type reaching a __post_init__ comparison
        raise ValueError(f"bad value under '{path or type(instance).__name__}': {exc}") from None


def simulator_config_from_dict(mapping: Mapping[str, Any]):
    """SimulatorConfig from a dict shaped like config/sim.yaml.

    ``cameras`` is a mapping ``name -> {enabled: bool, <CameraConfig keys>}``;
    cameras not listed keep their defaults, cameras with ``enabled: false``
    are left out of the simulation. ``faults`` is a list of sensor faults
    (``cottonsim_world.faults.schedule``), each checked against its kind's keys.
    """
    from cottonsim_world.simulator_config import SimulatorConfig   # local: it imports this module's users

    base = SimulatorConfig()
    mapping = dict(mapping or {})
    cameras_map = mapping.pop("cameras", None)
    faults = fault_schedule_from_list(mapping.pop("faults", None))
    config = apply_mapping(base, mapping)
    if cameras_map is not None:
        if not isinstance(cameras_map, Mapping):
            raise ValueError("config key 'cameras' must be a mapping of camera name -> settings")
        known = {name: cam for name, cam in base.cameras}
        cameras = []
        for name, cam in base.cameras:
            settings = dict(cameras_map.get(name) or {})
            if not settings.pop("enabled", True):
                continue
            cameras.append((name, apply_mapping(cam, settings, f"cameras.{name}")))
        for name in cameras_map:
            if name not in known:
                settings = dict(cameras_map[name] or {})
                if settings.pop("enabled", True):
                    cameras.append((name, apply_mapping(CameraConfig(), settings, f"cameras.{name}")))
        config = dataclasses.replace(config, cameras=tuple(cameras))
    if faults.faults:
        config = dataclasses.replace(config, faults=faults)
    return config
