"""Checks for config fields and inputs that raise a ValueError naming the bad key.

Every config dataclass validates its fields in ``__post_init__``; these helpers
keep the checks to one line each and the messages alike across packages
(``"<name> must be ..., got <value>"``). Each returns the value converted
(float, int, tuple or array) so a caller can store the clean form.
``require_fields`` applies one check to several fields of a config in one call.
"""
from __future__ import annotations

import math
from typing import Callable, Dict, Optional, Sequence, Tuple

import numpy as np

_NUMBER_TYPES = (int, float, np.integer, np.floating)


def is_number(value) -> bool:
    """True for ints and floats (numpy's too), False for bools and everything else."""
    return isinstance(value, _NUMBER_TYPES) and not isinstance(value, bool)


def require_instance(name: str, value, cls: type):
    """``value`` itself when it is an instance of ``cls``, else ValueError naming ``name`` and both types."""
    if not isinstance(value, cls):
        article = "an" if cls.__name__[:1].lower() in "aeiou" else "a"
        raise ValueError(f"{name} must be {article} {cls.__name__}, got {type(value).__name__}")
    return value


def require_bool(name: str, value) -> bool:
    """``value`` when it is True or False (not 0 or 1, not a string), else ValueError naming ``name``."""
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be true or false, got {value!r}")
    return value


def require_number(name: str, value, low: float = -math.inf, high: float = math.inf) -> float:
    """A finite number in [low, high] as a float."""
    if not is_number(value):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v < low or v > high:
        raise ValueError(f"{name} must be in [{low:g}, {high:g}], got {value!r}")
    return v


def require_positive(name: str, value, allow_zero: bool = False) -> float:
    """A finite number > 0 (>= 0 with ``allow_zero``) as a float."""
    if not is_number(value):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name} must be a finite number {'>=' if allow_zero else '>'} 0, got {value!r}")
    return v


def require_finite(name: str, value) -> float:
    """Any finite number as a float."""
    if not is_number(value):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def require_int(name: str, value, low: int = 0, high: Optional[int] = None) -> int:
    """An integer (not a bool, not a float) >= low (and <= high when given)."""
    if (isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low
            or (high is not None and value > high)):
        bound = f">= {low}" if high is None else f"in [{low}, {high}]"
        raise ValueError(f"{name} must be an integer {bound}, got {value!r}")
    return int(value)


def require_min_max(name: str, value, low: float = -math.inf, high: float = math.inf) -> Tuple[float, float]:
    """A (min, max) pair with low <= min <= max <= high, as floats."""
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        raise ValueError(f"{name} must be a (min, max) pair, got {value!r}")
    try:
        lo, hi = float(value[0]), float(value[1])
    except (TypeError, ValueError):
        raise ValueError(f"{name} must hold numbers, got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi or lo < low or hi > high:
        raise ValueError(f"{name} must satisfy {low:g} <= min <= max <= {high:g}, got {value!r}")
    return lo, hi


def require_finite_values(name: str, value, count: int, low: float = -math.inf) -> Tuple[float, ...]:
    """Exactly ``count`` finite numbers >= ``low`` as a tuple of floats (e.g. a map origin [x, y, yaw])."""
    try:
        values = tuple(value)
    except TypeError:
        raise ValueError(f"{name} must be {count} numbers, got {value!r}") from None
    if len(values) != count:
        raise ValueError(f"{name} must be {count} numbers, got {value!r}")
    values = tuple(require_finite(f"{name}[{i}]", v) for i, v in enumerate(values))
    if any(v < low for v in values):
        raise ValueError(f"{name} must be {count} finite numbers >= {low:g}, got {value!r}")
    return values


def require_finite_array(name: str, value, shape: Optional[Sequence[Optional[int]]] = None) -> np.ndarray:
    """A float array without NaN or inf; ``shape`` (None = any size on that axis) is checked when given."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numeric, got {value!r}") from None
    if shape is not None and (arr.ndim != len(shape)
                              or any(s is not None and s != n for s, n in zip(shape, arr.shape))):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return arr


def require_unit_vector(name: str, value, size: int, zero_name: str = "zero") -> np.ndarray:
    """``size`` finite numbers, not all zero, scaled to unit length (a direction, a quaternion) as an array.

    zero_name: what a zero vector is called in the error (``"{name} must not be {zero_name}"``).
    """
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (size,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be {size} finite numbers, got {value!r}")
    norm = float(np.linalg.norm(arr))
    if norm < 1e-9:
        raise ValueError(f"{name} must not be {zero_name}")
    return arr / norm


_FIELD_CHECKS: Dict[str, Callable] = {
    "flags": require_bool,
    "finite": require_finite,
    "positive": require_positive,
    "non_negative": lambda name, value: require_positive(name, value, allow_zero=True),
    "fractions": lambda name, value: require_number(name, value, 0.0, 1.0),
    "counts": lambda name, value: require_int(name, value, 1),
}


def require_fields(config, prefix: str = "", **fields: Sequence[str]) -> None:
    """Check several fields of ``config`` in one call, one rule per keyword, in the order given:

    flags: True or False; finite: finite numbers; positive: finite numbers > 0; non_negative: finite numbers >= 0;
    fractions: numbers in [0, 1]; counts: integers >= 1.
    E.g. ``require_fields(self, flags=("enabled",), positive=("rate_hz", "range_m"))``. The first bad
    field raises that check's ValueError naming ``prefix + field`` (prefix e.g. ``"CameraConfig."``).
    """
    for rule, names in fields.items():
        if rule not in _FIELD_CHECKS:
            raise TypeError(f"require_fields: unknown rule {rule!r} (one of {', '.join(_FIELD_CHECKS)})")
        if isinstance(names, str):
            raise TypeError(f"require_fields: {rule} must be a sequence of field names, not the string {names!r}")
        for name in names:
            _FIELD_CHECKS[rule](prefix + name, getattr(config, name))
