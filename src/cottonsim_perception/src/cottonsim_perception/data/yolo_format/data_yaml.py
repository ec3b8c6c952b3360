"""Ultralytics' data.yaml: reading, writing, class names.

Keys, read as Ultralytics reads them:

* ``path``: the dataset root, absolute or relative to the yaml's folder
  (absent or empty: the yaml's folder);
* ``train``, ``val``, ``test``: each an image folder (searched recursively),
  a file listing images (one path per line, relative paths from that file's
  folder), a single image, or a list of these; relative to ``path``; absent
  or empty: the dataset has no such split (see ``layout.list_pairs``);
* ``names``: the class names, a list or an {id: name} mapping with ids
  0..n-1 (``nc`` is written for other tools but not read: it is len(names)).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Tuple, Union

from .labels import DETECTION_CLASS_NAMES, SEGMENTATION_CLASS_NAMES, LabelFormatError, check_task

#: The file name of a dataset's yaml inside its folder.
DATA_YAML = "data.yaml"

#: One split's entry: a path, or a tuple of paths ('' when the split is absent).
SplitEntry = Union[str, Tuple[str, ...]]

_SPLIT_KEYS = {"train": "train", "val": "val", "valid": "val", "test": "test"}


@dataclass(frozen=True)
class DataYaml:
    """Contents of an Ultralytics data.yaml.

    path: dataset root (absolute after :func:`read_data_yaml`; when writing,
    '' writes no key: the yaml's folder); train, val, test: what each split's
    key holds (a path or a tuple of paths relative to ``path``; '' when
    absent); names: class names in id order.
    """

    path: str
    train: SplitEntry
    val: SplitEntry
    test: SplitEntry = ""
    names: Tuple[str, ...] = field(default_factory=tuple)

    def entries(self, split: str) -> Tuple[str, ...]:
        """The paths that ``split`` names ('valid' is 'val'); () when the yaml names none."""
        key = _SPLIT_KEYS.get(split)
        value = getattr(self, key) if key else ""
        if isinstance(value, str):
            return (value,) if value else ()
        return tuple(v for v in value if v)


def _split_entry(raw: dict, key: str, path: str) -> SplitEntry:
    value = raw.get(key)
    if value is None or value == "":
        return ""
    if isinstance(value, str):
        return value
    if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value):
        return tuple(value)
    raise LabelFormatError(f"{path}: '{key}' must be a path or a list of paths, got {value!r}")


def read_data_yaml(path: str) -> DataYaml:
    """Read a data.yaml (see the module docstring); ``path`` of the result is absolute.

    Raises :class:`LabelFormatError` naming the file for unreadable or
    non-strict YAML (a key given twice), a top level that is not a mapping, bad ``names`` or a split key that is not
    a path or a list of paths.
    """
    from cottonsim_common.config.yaml_files import load_yaml_file

    try:
        raw = load_yaml_file(path)
    except ValueError as exc:
        raise LabelFormatError(f"data.yaml: {exc}") from None
    if not isinstance(raw, dict):
        raise LabelFormatError(f"{path}: expected a mapping at top level")
    names = raw.get("names", [])
    if isinstance(names, dict):
        try:
            ids = sorted(int(k) for k in names)
        except (TypeError, ValueError):
            raise LabelFormatError(f"{path}: 'names' keys must be integer class ids") from None
        if ids != list(range(len(ids))):
            raise LabelFormatError(f"{path}: 'names' ids must be 0..{len(ids) - 1}")
        names = [names[k] if k in names else names[str(k)] for k in ids]
    if not isinstance(names, (list, tuple)):
        raise LabelFormatError(f"{path}: 'names' must be a list or a mapping")
    root = raw.get("path") or ""
    if not isinstance(root, str):
        raise LabelFormatError(f"{path}: 'path' must be a folder path, got {root!r}")
    if not os.path.isabs(root):
        root = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)), root))
    return DataYaml(path=root, train=_split_entry(raw, "train", path), val=_split_entry(raw, "val", path),
                    test=_split_entry(raw, "test", path), names=tuple(str(n) for n in names))


def write_data_yaml(path: str, data: DataYaml) -> None:
    """Write a data.yaml (names as a list, a tuple entry as a list).

    An empty ``data.path`` writes no 'path' key: readers (this module, Ultralytics) then take
    the yaml's own folder as the root, so the dataset folder can be moved or copied.
    """
    import yaml

    def entry(value: SplitEntry):
        return value if isinstance(value, str) else list(value)

    content = {"path": data.path} if data.path else {}
    content.update({"train": entry(data.train), "val": entry(data.val), "test": entry(data.test),
                    "nc": len(data.names), "names": list(data.names)})
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", encoding="utf-8") as fh:
        yaml.safe_dump(content, fh, sort_keys=False)


def class_names_for(root: str, task: str) -> Tuple[str, ...]:
    """The dataset's class names: from DIR/data.yaml if present, else the paper's."""
    check_task(task)
    yaml_path = os.path.join(root, DATA_YAML)
    if os.path.isfile(yaml_path):
        names = read_data_yaml(yaml_path).names
        if names:
            return names
    return SEGMENTATION_CLASS_NAMES if task == "seg" else DETECTION_CLASS_NAMES
