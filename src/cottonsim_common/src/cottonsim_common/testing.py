"""Checks the packages' unit tests share (no ROS, no pytest needed).

``assert_config_rejects`` is the test every config dataclass gets: a bad
value for one key, the others left at their defaults, must raise a
ValueError that names that key (the house rule for config errors).
"""
from __future__ import annotations

import re
from typing import Tuple


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
