"""Where a dataset's images, labels and ignore boxes are: splits and image / label pairs.

Layouts understood by :func:`list_pairs`, tried in this order:

* a ``DIR/data.yaml`` whose key for the split names image folders, image
  list files or images (see ``data_yaml``), as Ultralytics reads it;
* Roboflow export (the paper's data): ``DIR/{train,valid,test}/images``;
* Ultralytics folders: ``DIR/images/{train,val,test}``.

The split names 'valid' and 'val' are synonyms. An image's label file is
found by Ultralytics' rule: the last ``images`` folder of its path becomes
``labels`` and the extension ``.txt`` (ignore boxes: ``ignore``).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

from .data_yaml import DATA_YAML, read_data_yaml
from .labels import LabelFormatError, LabelInstance, read_label_file

IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp")

#: Folder of the ignore-box files, beside ``labels`` (see :func:`ignore_path_for`).
IGNORE_FOLDER = "ignore"

_SPLIT_ALIASES = {"valid": ("valid", "val"), "val": ("val", "valid"),
                  "train": ("train",), "test": ("test",)}


@dataclass(frozen=True)
class ImageLabelPair:
    """One image file and the label file that belongs to it (which may not exist)."""

    image_path: str
    label_path: str


def _sibling_txt_path(image_path: str, folder: str) -> str:
    """The image's path with its last 'images' folder renamed ``folder`` and extension '.txt'."""
    head, name = os.path.split(image_path)
    parts = head.split(os.sep)
    for i in range(len(parts) - 1, -1, -1):
        if parts[i] == "images":
            parts[i] = folder
            break
    stem = os.path.splitext(name)[0]
    return os.path.join(os.sep.join(parts), stem + ".txt")


def label_path_for(image_path: str) -> str:
    """Ultralytics' rule: the last '/images/' folder becomes '/labels/', extension '.txt'."""
    return _sibling_txt_path(image_path, "labels")


def ignore_path_for(image_path: str) -> str:
    """The image's ignore-box file: the last '/images/' folder becomes '/ignore/'.

    Ignore boxes (our extension of the format, written by the dataset
    generator for bolls outside its labelling rules; Ultralytics does not
    read them) are YOLO box lines of objects that are neither required nor
    forbidden: an unmatched prediction lying on one is not a false positive
    (``evaluate``), and the training loss does not push the anchors inside
    one towards background (``nn.loss``).
    """
    return _sibling_txt_path(image_path, IGNORE_FOLDER)


def read_ignore_instances(image_path: str) -> List[LabelInstance]:
    """The image's ignore boxes as box lines (normalised; empty when it has no ignore file).

    Raises :class:`LabelFormatError` for a malformed ignore file.
    """
    path = ignore_path_for(image_path)
    return read_label_file(path, "det", 1) if os.path.isfile(path) else []


def read_ignore_boxes(image_path: str, width: int, height: int) -> np.ndarray:
    """(K, 4) float32 ignore boxes xyxy [px] of an image (empty when it has no ignore file)."""
    return np.array([inst.box_xyxy_px(width, height) for inst in read_ignore_instances(image_path)],
                    dtype=np.float32).reshape(-1, 4)


def _is_image(path: str) -> bool:
    return path.lower().endswith(IMAGE_EXTENSIONS)


def _list_images(folder: str) -> List[str]:
    files = []
    for dirpath, _dirs, names in os.walk(folder):
        for n in names:
            if _is_image(n):
                files.append(os.path.join(dirpath, n))
    return sorted(files)


def _read_image_list(path: str) -> List[str]:
    """The images a list file names, one per line (relative paths from the file's folder)."""
    try:
        with open(path, "r", encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise LabelFormatError(f"{path}: cannot read the image list ({exc})") from None
    base = os.path.dirname(os.path.abspath(path))
    images = []
    for number, line in enumerate(lines, start=1):
        entry = line.strip()
        if not entry:
            continue
        image = entry if os.path.isabs(entry) else os.path.normpath(os.path.join(base, entry))
        if not _is_image(image):
            raise LabelFormatError(f"{path}:{number}: {entry!r} is not an image ({', '.join(IMAGE_EXTENSIONS)})")
        if not os.path.isfile(image):
            raise LabelFormatError(f"{path}:{number}: image {entry!r} does not exist")
        images.append(image)
    return images


def _resolve_entry(root: str, entry: str) -> str:
    """An entry of a data.yaml split key as a path: absolute, or relative to the dataset root.

    Like Ultralytics, an entry '../X' that does not exist is also tried as 'X'
    (Roboflow exports write '../valid/images' for a yaml inside the dataset).
    """
    path = entry if os.path.isabs(entry) else os.path.normpath(os.path.join(root, entry))
    if not os.path.exists(path) and entry.startswith("../"):
        stripped = os.path.normpath(os.path.join(root, entry[3:]))
        if os.path.exists(stripped):
            return stripped
    return path


def _yaml_split_images(yaml_path: str, split: str, tried: List[str]) -> Optional[Tuple[List[str], str]]:
    """(images, where) of ``split`` as data.yaml names it; None when it names none or none of its paths exist."""
    data = read_data_yaml(yaml_path)
    entries = data.entries(split)
    if not entries:
        tried.append(f"{yaml_path} (no '{split}' entry)")
        return None
    paths = [_resolve_entry(data.path, e) for e in entries]
    missing = [p for p in paths if not os.path.exists(p)]
    if len(missing) == len(paths):
        tried.extend(f"{p} (from {yaml_path})" for p in paths)
        return None
    if missing:
        raise LabelFormatError(f"{yaml_path}: '{split}' names {missing[0]!r}, which does not exist")
    images: List[str] = []
    for path in paths:
        if os.path.isdir(path):
            images += _list_images(path)
        elif _is_image(path):
            images.append(path)
        else:
            images += _read_image_list(path)
    return sorted(set(images)), ", ".join(repr(p) for p in paths)


def _locate_split(root: str, split: str) -> Tuple[List[str], str]:
    """(sorted image files, where they are) of ``split`` under ``root`` (any of the layouts; may be empty).

    Raises :class:`LabelFormatError` naming the places tried when the split
    is in none of them, and for a malformed data.yaml or image list.
    """
    if not os.path.isdir(root):
        raise LabelFormatError(f"dataset folder {root!r} does not exist")
    tried: List[str] = []
    yaml_path = os.path.join(root, DATA_YAML)
    if os.path.isfile(yaml_path):
        found = _yaml_split_images(yaml_path, split, tried)
        if found is not None:
            return found
    for name in _SPLIT_ALIASES.get(split, (split,)):
        for folder in (os.path.join(root, name, "images"), os.path.join(root, "images", name)):
            tried.append(folder)
            if os.path.isdir(folder):
                return _list_images(folder), repr(folder)
    raise LabelFormatError(f"split {split!r} not found under {root!r}; tried: {', '.join(tried)}")


def list_pairs(root: str, split: str) -> List[ImageLabelPair]:
    """Sorted image / label pairs of a split (see the module docstring for where it is looked for).

    Raises :class:`LabelFormatError` when the split is in none of the layouts
    (naming the places tried) or has no images, and for a malformed data.yaml
    or image list.
    """
    images, where = _locate_split(root, split)
    if not images:
        raise LabelFormatError(f"no images ({', '.join(IMAGE_EXTENSIONS)}) in {where}")
    return [ImageLabelPair(p, label_path_for(p)) for p in images]
