"""YAML files read strictly: a key given twice in one mapping is an error.

Why: PyYAML (and so roslaunch's ``rosparam load``) keeps the last of two equal
keys without a word, so a setting written twice in a long config file silently
overrides the first, and the file no longer says what runs. Every YAML file
the project reads goes through :func:`load_yaml_file` or :func:`load_yaml_text`,
which refuse such a file with an error naming the key and both lines.
The safe loader is used: tags that build Python objects are refused too.
"""
from __future__ import annotations

import os
from typing import Any, Optional

import yaml

try:                                        # libyaml's parser when present: same result, faster
    _BaseLoader = yaml.CSafeLoader
except AttributeError:                      # pragma: no cover - PyYAML built without libyaml
    _BaseLoader = yaml.SafeLoader


class DuplicateKeyError(ValueError):
    """A mapping names the same key twice. ``key``, ``first_line`` and ``second_line`` (1-based) say where."""

    def __init__(self, source: str, key: Any, first_line: int, second_line: int):
        self.source = source
        self.key = key
        self.first_line = first_line
        self.second_line = second_line
        super().__init__(f"{source}: key {key!r} is given twice, on lines {first_line} and {second_line} "
                         f"(YAML would silently keep the second; remove one)")


class YamlSyntaxError(ValueError):
    """Text that is not (safe) YAML; ``line`` (1-based, or None) says where the parser stopped."""

    def __init__(self, source: str, problem: str, line: Optional[int]):
        self.source = source
        self.problem = problem
        self.line = line
        where = f" (line {line})" if line is not None else ""
        super().__init__(f"{source}: not valid YAML{where}: {problem}")


class _StrictLoader(_BaseLoader):
    """A safe loader whose mappings refuse a repeated key."""

    source_name = "<yaml>"

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            first_line = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":      # '<<' merges are YAML's own mechanism
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    hash(key)
                except TypeError:
                    continue                                      # the base class reports unhashable keys
                line = key_node.start_mark.line + 1
                if key in first_line:
                    raise DuplicateKeyError(self.source_name, key, first_line[key], line)
                first_line[key] = line
        return super().construct_mapping(node, deep=deep)


def load_yaml_text(text: str, source: str = "<yaml>") -> Any:
    """The document of ``text`` (None when empty); ``source`` names it in errors.

    Raises :class:`DuplicateKeyError` for a repeated key and
    :class:`YamlSyntaxError` for text that is not YAML, both ``ValueError``
    naming ``source``.
    """
    loader = _StrictLoader(text)
    loader.source_name = source
    try:
        return loader.get_single_data()
    except DuplicateKeyError:
        raise
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise YamlSyntaxError(source, getattr(exc, "problem", None) or str(exc),
                              None if mark is None else mark.line + 1) from None
    finally:
        loader.dispose()


def load_yaml_file(path: "os.PathLike[str] | str", default: Optional[Any] = None) -> Any:
    """The document of the YAML file at ``path``, or ``default`` when the file is empty.

    Raises ``ValueError`` naming the file when it cannot be read, is not
    YAML, or repeats a key in a mapping (:class:`DuplicateKeyError`).
    """
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except OSError as exc:
        raise ValueError(f"cannot read YAML file {path!r}: {exc.strerror or exc}") from None
    data = load_yaml_text(text, source=path)
    return default if data is None else data
