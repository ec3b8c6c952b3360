"""The robot's own body as boxes in the arm's base frame, read from the robot description (URDF text).

The arm must not hit the Husky, its top plate, the sensors or the control box.
Their shapes are in the URDF (the ROS layer reads it from /robot_description;
tests read the committed file), so this module takes the URDF as text and
returns a BoxSet: every box, cylinder and sphere of every link that is not
part of the arm, posed with the joints at zero (the wheels are cylinders about
their axles, the same at any angle), expressed in the arm's base frame. A
cylinder or sphere becomes its bounding box. Optionally the ground is added as
a slab under base_footprint.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Dict, List, Optional, Set, Tuple

import numpy as np

from cottonsim_manipulation.planning.collision import BoxSet


def _floats(text: Optional[str], count: int, what: str) -> np.ndarray:
    if text is None:
        return np.zeros(count)
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        raise ValueError(f"URDF {what}: {text!r} is not {count} numbers") from None
    if values.shape != (count,) or not np.all(np.isfinite(values)):
        raise ValueError(f"URDF {what}: {text!r} is not {count} finite numbers")
    return values


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF rpy: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def _origin(element: Optional[ET.Element], what: str) -> np.ndarray:
    t = np.eye(4)
    if element is None:
        return t
    t[:3, 3] = _floats(element.get("xyz"), 3, f"{what} origin xyz")
    t[:3, :3] = rpy_matrix(*_floats(element.get("rpy"), 3, f"{what} origin rpy"))
    return t


def _shape_box(geometry: ET.Element, what: str) -> Optional[np.ndarray]:
    """Half extents of the bounding box of a geometry in its origin frame; None for meshes."""
    box = geometry.find("box")
    if box is not None:
        return _floats(box.get("size"), 3, f"{what} box size") / 2.0
    cyl = geometry.find("cylinder")
    if cyl is not None:
        r = float(_floats(cyl.get("radius"), 1, f"{what} cylinder radius")[0])
        length = float(_floats(cyl.get("length"), 1, f"{what} cylinder length")[0])
        return np.array([r, r, length / 2.0])
    sphere = geometry.find("sphere")
    if sphere is not None:
        r = float(_floats(sphere.get("radius"), 1, f"{what} sphere radius")[0])
        return np.array([r, r, r])
    return None


def body_boxes_from_urdf(
    urdf_xml: str,
    arm_base_frame: str = "ur5e_base",
    arm_root_link: str = "ur5e_base_link",
    source: str = "visual",
    ground_link: Optional[str] = "base_footprint",
    ground_half_size_m: float = 5.0,
) -> BoxSet:
    """Boxes of every link outside the arm, in the frame `arm_base_frame`.

    arm_root_link: the arm's first link; it and every link below it are the arm
        and are left out. source: 'visual' (default: the shapes as drawn, which
        include the sensors) or 'collision'. ground_link: a link on the ground
        (its z = 0 is the ground); a slab 0.1 m thick and 2 * ground_half_size_m
        wide is added under it ('ground'); None for no ground.
    ValueError on malformed XML, unknown frames or a link with two parents.
    """
    if source not in ("visual", "collision"):
        raise ValueError(f"source must be 'visual' or 'collision', got {source!r}")
    try:
        root = ET.fromstring(urdf_xml)
    except ET.ParseError as err:
        raise ValueError(f"the robot description is not valid XML: {err}") from None
    links = {el.get("name"): el for el in root.findall("link")}
    parent_of: Dict[str, Tuple[str, np.ndarray]] = {}
    children: Dict[str, List[str]] = {}
    for joint in root.findall("joint"):
        name = joint.get("name", "?")
        parent_el, child_el = joint.find("parent"), joint.find("child")
        if parent_el is None or child_el is None:
            raise ValueError(f"URDF joint {name} lacks a parent or child")
        parent, child = parent_el.get("link"), child_el.get("link")
        if child in parent_of:
            raise ValueError(f"URDF link {child} has two parent joints")
        parent_of[child] = (parent, _origin(joint.find("origin"), f"joint {name}"))
        children.setdefault(parent, []).append(child)
    for needed in (arm_base_frame, arm_root_link) + ((ground_link,) if ground_link else ()):
        if needed not in links:
            raise ValueError(f"the robot description has no link {needed!r}")

    cache: Dict[str, np.ndarray] = {}

    def root_pose(link: str) -> np.ndarray:
        if link not in cache:
            if link in parent_of:
                parent, origin = parent_of[link]
                cache[link] = root_pose(parent) @ origin
            else:
                cache[link] = np.eye(4)
        return cache[link]

    arm: Set[str] = set()
    stack = [arm_root_link]
    while stack:
        link = stack.pop()
        arm.add(link)
        stack.extend(children.get(link, []))

    to_arm = np.linalg.inv(root_pose(arm_base_frame))
    centres, rotations, halves, names = [], [], [], []
    for name, link in links.items():
        if name in arm:
            continue
        for index, element in enumerate(link.findall(source)):
            geometry = element.find("geometry")
            half = _shape_box(geometry, f"link {name}") if geometry is not None else None
            if half is None:
                continue
            pose = to_arm @ root_pose(name) @ _origin(element.find("origin"), f"link {name} {source}")
            centres.append(pose[:3, 3])
            rotations.append(pose[:3, :3])
            halves.append(half)
            names.append(f"{name}/{index}")
    if ground_link:
        pose = to_arm @ root_pose(ground_link)
        centres.append(pose[:3, 3] - 0.05 * pose[:3, 2])
        rotations.append(pose[:3, :3])
        halves.append(np.array([ground_half_size_m, ground_half_size_m, 0.05]))
        names.append("ground")
    if not names:
        return BoxSet.empty()
    return BoxSet(np.array(centres), np.array(rotations), np.array(halves), tuple(names))
