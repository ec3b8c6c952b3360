"""Checks the packages' unit tests share (no ROS, no pytest needed).

``assert_config_rejects`` is the test every config dataclass gets: a bad
value for one key, the others left at their defaults, must raise a
ValueError that names that key (the house rule for config errors).
``load_script`` imports an executable of a package's ``scripts/`` (a file
without the .py suffix) as a module, so a test can call its ``main``.
"""
from __future__ import annotations

import importlib.machinery
import importlib.util
import pathlib
import re
from types import ModuleType
from typing import Tuple


def load_script(path) -> ModuleType:
    """The Python script at ``path`` (any file name) loaded as a module named after the file."""
    path = pathlib.Path(path)
    loader = importlib.machinery.SourceFileLoader(f"{path.name}_script", str(path))
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader(loader.name, loader))
    loader.exec_module(module)
    return module


def assert_config_rejects(config_cls: type, *cases: Tuple) -> None:
    """Each case (key, bad value) or (key, bad value, regex) must make ``config_cls(key=bad value)`` raise a
    ValueError whose message contains ``key`` (and matches ``regex`` when given); AssertionError otherwise."""
    for case in cases:
        key, value = case[0], case[1]
        pattern = case[2] if len(case) > 2 else re.escape(key)
        call = f"{config_cls.__name__}({key}={value!r})"
        try:
            config_cls(**{key: value})
        except ValueError as exc:
            if key not in str(exc) or not re.search(pattern, str(exc)):
                raise AssertionError(f"{call}: the error does not name {key!r} (or match {pattern!r}): {exc}") from exc
        else:
            raise AssertionError(f"{call} was accepted")
