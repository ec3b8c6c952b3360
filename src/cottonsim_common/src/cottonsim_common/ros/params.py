"""Fill the cores' frozen config dataclasses from ROS parameters.

Why: every navigation node owns one config dataclass per algorithm whose
defaults and validation live in the core (``__post_init__``). The node only
has to look up, for each field, whether a parameter of the same name is set
and pass it on. Doing that here, once, keeps the nodes short and makes every
bad parameter fail the same way: a ``ValueError`` that names the parameter
(e.g. ``parameter ~frequency: must be a number, got 'fast'``), which the node's
``main`` turns into ``rospy.logfatal`` + a non-zero exit.

Conversions from the YAML/XML-RPC types rosparam hands back:

* ``float`` fields take ints and floats (not bools, not strings);
* ``int`` fields take integers (a float is accepted only if it is integral);
* ``bool`` fields take bools, and the strings "true"/"false" (roslaunch
  ``<param value="true">`` without a type gives a bool already);
* ``str`` fields take strings;
* ``Tuple[...]`` / ``Optional[Tuple[...]]`` fields take lists and tuples,
  converted element-wise (``Tuple[float, ...]`` or fixed length);
* anything else is passed through unchanged for the dataclass to validate.

The parameter server access is injectable (``get_param`` / ``has_param``) so
this module is unit-tested without a ROS master; by default it uses rospy.
"""
from __future__ import annotations

import dataclasses
import math
import re
import typing
from typing import Any, Callable, Dict, Optional, Tuple, Type, TypeVar

T = TypeVar("T")

_MISSING = object()


def dict_parameter_server(values: Dict[str, Any]) -> Tuple[Callable[..., Any], Callable[[str], bool]]:
    """(get_param, has_param) over a dict of full parameter names, for configs built without a master.

    ``get_param(name)`` raises KeyError for a missing name, like rospy; ``get_param(name, default)``
    returns the default.
    """
    missing = object()

    def get_param(name: str, default: Any = missing) -> Any:
        if name in values:
            return values[name]
        if default is missing:
            raise KeyError(name)
        return default

    return get_param, (lambda name: name in values)


def _rospy_access():
    import rospy  # imported lazily: the unit tests inject a dict instead

    return rospy.get_param, rospy.has_param


def _coerce(value: Any, hint: Any, name: str) -> Any:
    """Convert one rosparam value to the field type ``hint`` or raise ValueError naming ``name``."""
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin is typing.Union:                           # Optional[X] (and simple unions)
        if value is None and type(None) in args:
            return None
        options = [a for a in args if a is not type(None)]
        if len(options) == 1:
            return _coerce(value, options[0], name)
        return value
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"parameter {name}: must be a number, got {value!r}")
        value = float(value)
        if math.isnan(value):
            raise ValueError(f"parameter {name}: must not be NaN")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"parameter {name}: must be an integer, got {value!r}")
        if isinstance(value, float):
            if not (math.isfinite(value) and value.is_integer()):
                raise ValueError(f"parameter {name}: must be an integer, got {value!r}")
            value = int(value)
        return value
    if hint is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.strip().lower() in ("true", "false"):
            return value.strip().lower() == "true"
        raise ValueError(f"parameter {name}: must be true or false, got {value!r}")
    if hint is str:
        if not isinstance(value, str):
            raise ValueError(f"parameter {name}: must be a string, got {value!r}")
        return value
    if origin in (tuple, typing.Tuple):
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"parameter {name}: must be a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_coerce(v, args[0], f"{name}[{i}]") for i, v in enumerate(value))
        if args and args != ((),):
            if len(value) != len(args):
                raise ValueError(f"parameter {name}: must be a list of {len(args)} values, got {value!r}")
            return tuple(_coerce(v, a, f"{name}[{i}]") for i, (v, a) in enumerate(zip(value, args)))
        return tuple(value)
    return value


def config_from_params(config_cls: Type[T], prefix: str = "~", overrides: Optional[Dict[str, Any]] = None,
                       get_param: Optional[Callable[..., Any]] = None,
                       has_param: Optional[Callable[[str], bool]] = None) -> T:
    """Build ``config_cls`` (a dataclass) from the parameters ``<prefix><field>``.

    Fields without a parameter keep the dataclass default. ``overrides``
    (field -> value) wins over both, for values a node decides itself.
    Raises ValueError naming the parameter when a value has the wrong type or
    the dataclass's own validation refuses it.
    """
    if not (isinstance(config_cls, type) and dataclasses.is_dataclass(config_cls)):
        raise ValueError(f"config_from_params needs a dataclass type, got {config_cls!r}")
    if get_param is None or has_param is None:
        default_get, default_has = _rospy_access()
        get_param = get_param or default_get
        has_param = has_param or default_has
    hints = typing.get_type_hints(config_cls)
    kwargs: Dict[str, Any] = {}
    for field in dataclasses.fields(config_cls):
        if not field.init:
            continue
        name = prefix + field.name
        if overrides and field.name in overrides:
            kwargs[field.name] = overrides[field.name]
        elif has_param(name):
            kwargs[field.name] = _coerce(get_param(name), hints.get(field.name, Any), name)
    try:
        return config_cls(**kwargs)
    except (ValueError, TypeError) as exc:
        # the dataclass names its field in the message; say which parameter that is
        text = str(exc)
        named = [f.name for f in dataclasses.fields(config_cls)
                 if re.search(rf"(?<![A-Za-z0-9_]){re.escape(f.name)}(?![A-Za-z0-9_])", text)]
        where = f"parameter {prefix}{max(named, key=len)}" if named else f"parameters {prefix}*"
        raise ValueError(f"{where}: {text}") from None


def typed_param(name: str, default: Any, get_param: Optional[Callable[..., Any]] = None,
                minimum: Optional[float] = None) -> Any:
    """One node-level parameter with the type of ``default`` (float, int, bool, str, tuple).

    ``minimum`` (numbers only) refuses smaller values. Raises ValueError
    naming the parameter. Use it for settings that belong to the node, not to
    an algorithm's config (frame ids, topic names, rates).
    """
    if get_param is None:
        get_param = _rospy_access()[0]
    value = get_param(name, _MISSING)
    if value is _MISSING:
        return default
    if isinstance(default, bool):
        hint: Any = bool
    elif isinstance(default, tuple):
        hint = typing.Tuple[float, ...] if all(isinstance(v, (int, float)) for v in default) else tuple
    elif default is None:
        return value
    else:
        hint = type(default)
    value = _coerce(value, hint, name)
    if minimum is not None and isinstance(value, (int, float)) and not isinstance(value, bool):
        if not (value >= minimum):
            raise ValueError(f"parameter {name}: must be >= {minimum}, got {value!r}")
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"parameter {name}: must be finite, got {value!r}")
    return value
