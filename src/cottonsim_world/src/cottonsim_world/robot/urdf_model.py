"""A small pure-Python URDF reader: links, joints and transforms along the tree.

The simulator places its sensors and reads the UR5e joint limits from the
robot's URDF (cottonsim_description/urdf/cottonsim_robot.urdf), so the URDF is
the single source of truth for the robot's geometry. This module reads that
XML with xml.etree and numpy only (no ROS, no urdf_parser_py, no KDL) and
composes joint origins into 4x4 homogeneous transforms.

Conventions (URDF / REP-103): a joint's origin is the pose of the child frame
in the parent frame at zero joint position; rpy is roll about x, pitch about
y, yaw about z, about the fixed parent axes: R = Rz(yaw) @ Ry(pitch) @ Rx(roll).
``transform(a, b)`` returns T_a_b, the pose of frame b expressed in frame a,
so ``transform(a, b) @ p_b`` gives the point p_b in frame a. Lengths in
metres, angles in radians.

Malformed input (not XML, missing parent/child, unknown links, a link with two
parents, cycles, bad numbers) raises ValueError naming the problem.
"""
from __future__ import annotations

import math
import pathlib
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from cottonsim_common.transforms import invert

JOINT_TYPES = ("fixed", "revolute", "continuous", "prismatic", "floating", "planar")
# Joint types whose motion this reader can apply (one scalar position).
_SCALAR_JOINTS = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class JointLimits:
    """Limits of a joint: position lower/upper [rad or m], velocity
    [rad/s or m/s] and effort [N m or N], as in the URDF <limit> tag."""

    lower: float
    upper: float
    velocity: float
    effort: float


@dataclass(frozen=True)
class Geometry:
    """One visual or collision primitive of a link.

    kind: 'box' (size = full extents x, y, z [m]), 'cylinder' (radius, length
    [m]; axis along z of origin), 'sphere' (radius,) or 'mesh' (scale x, y, z;
    filename in ``filename``). origin: 4x4 pose in the link frame.
    """

    kind: str
    size: Tuple[float, ...]
    origin: np.ndarray
    filename: str = ""
    material: str = ""


@dataclass(frozen=True)
class Link:
    """A URDF link: name, mass [kg] (0 when it has no <inertial>), its
    visual and collision geometry."""

    name: str
    mass_kg: float = 0.0
    visuals: Tuple[Geometry, ...] = ()
    collisions: Tuple[Geometry, ...] = ()


@dataclass(frozen=True)
class Joint:
    """A URDF joint.

    origin: 4x4 pose of the child frame in the parent frame at position 0.
    axis: unit 3-vector in the child (= joint) frame. limits: JointLimits or
    None (fixed/continuous joints may have none).
    """

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    limits: Optional[JointLimits] = None

    @property
    def is_fixed(self) -> bool:
        return self.type == "fixed"

    def motion(self, position: float) -> np.ndarray:
        """4x4 motion of the child frame for joint position q [rad or m]."""
        out = np.eye(4)
        if self.type in ("revolute", "continuous"):
            out[:3, :3] = axis_angle_matrix(self.axis, position)
        elif self.type == "prismatic":
            out[:3, 3] = self.axis * position
        elif self.type != "fixed":
            raise ValueError(f"joint {self.name!r}: type {self.type!r} is not supported by transform()")
        return out

    def transform(self, position: float = 0.0) -> np.ndarray:
        """T_parent_child at joint position q."""
        return self.origin @ self.motion(position)


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """3x3 rotation Rz(yaw) @ Ry(pitch) @ Rx(roll) (URDF rpy) [rad]."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def axis_angle_matrix(axis: np.ndarray, angle: float) -> np.ndarray:
    """3x3 rotation by angle [rad] about a unit axis (Rodrigues)."""
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def pose_matrix(xyz: Sequence[float], rpy: Sequence[float]) -> np.ndarray:
    """4x4 homogeneous transform from a translation [m] and URDF rpy [rad]."""
    out = np.eye(4)
    out[:3, :3] = rpy_matrix(*rpy)
    out[:3, 3] = xyz
    return out


def _floats(text: Optional[str], count: int, what: str, default: Optional[Sequence[float]] = None) -> Tuple[float, ...]:
    """Parse 'count' whitespace-separated finite numbers, naming 'what' on error."""
    if text is None:
        if default is None:
            raise ValueError(f"{what} is missing")
        return tuple(float(v) for v in default)
    parts = text.split()
    if len(parts) != count:
        raise ValueError(f"{what} must have {count} numbers, got {text!r}")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise ValueError(f"{what} is not numeric: {text!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"{what} is not finite: {text!r}")
    return values


def _origin(element: Optional[ET.Element], what: str) -> np.ndarray:
    if element is None:
        return np.eye(4)
    xyz = _floats(element.get("xyz"), 3, f"{what} origin xyz", (0, 0, 0))
    rpy = _floats(element.get("rpy"), 3, f"{what} origin rpy", (0, 0, 0))
    return pose_matrix(xyz, rpy)


def _geometry(element: ET.Element, what: str) -> Geometry:
    origin = _origin(element.find("origin"), what)
    geo = element.find("geometry")
    if geo is None or len(geo) == 0:
        raise ValueError(f"{what} has no <geometry>")
    shape = geo[0]
    material_el = element.find("material")
    material = material_el.get("name", "") if material_el is not None else ""
    if shape.tag == "box":
        return Geometry("box", _floats(shape.get("size"), 3, f"{what} box size"), origin, material=material)
    if shape.tag == "cylinder":
        radius = _floats(shape.get("radius"), 1, f"{what} cylinder radius")[0]
        length = _floats(shape.get("length"), 1, f"{what} cylinder length")[0]
        return Geometry("cylinder", (radius, length), origin, material=material)
    if shape.tag == "sphere":
        return Geometry("sphere", _floats(shape.get("radius"), 1, f"{what} sphere radius"), origin, material=material)
    if shape.tag == "mesh":
        filename = shape.get("filename")
        if not filename:
            raise ValueError(f"{what} mesh has no filename")
        scale = _floats(shape.get("scale"), 3, f"{what} mesh scale", (1, 1, 1))
        return Geometry("mesh", scale, origin, filename=filename, material=material)
    raise ValueError(f"{what} has unknown geometry <{shape.tag}>")


def _parse_link(element: ET.Element) -> Link:
    name = element.get("name")
    if not name:
        raise ValueError("a <link> has no name")
    mass = 0.0
    inertial = element.find("inertial")
    if inertial is not None:
        mass_el = inertial.find("mass")
        if mass_el is None:
            raise ValueError(f"link {name!r}: <inertial> has no <mass>")
        mass = _floats(mass_el.get("value"), 1, f"link {name!r} mass")[0]
        if mass < 0.0:
            raise ValueError(f"link {name!r}: negative mass {mass}")
    visuals = tuple(_geometry(v, f"link {name!r} visual") for v in element.findall("visual"))
    collisions = tuple(_geometry(c, f"link {name!r} collision") for c in element.findall("collision"))
    return Link(name, mass, visuals, collisions)


def _parse_joint(element: ET.Element) -> Joint:
    name = element.get("name")
    if not name:
        raise ValueError("a <joint> has no name")
    jtype = element.get("type")
    if jtype not in JOINT_TYPES:
        raise ValueError(f"joint {name!r}: type {jtype!r} is not one of {JOINT_TYPES}")
    links = {}
    for tag in ("parent", "child"):
        el = element.find(tag)
        if el is None or not el.get("link"):
            raise ValueError(f"joint {name!r} has no <{tag} link=...>")
        links[tag] = el.get("link")
    origin = _origin(element.find("origin"), f"joint {name!r}")
    axis_el = element.find("axis")
    axis = np.array(_floats(axis_el.get("xyz") if axis_el is not None else None, 3, f"joint {name!r} axis", (1, 0, 0)))
    norm = float(np.linalg.norm(axis))
    if jtype in _SCALAR_JOINTS:
        if norm < 1e-9:
            raise ValueError(f"joint {name!r}: axis is zero")
        axis = axis / norm
    limits = None
    limit_el = element.find("limit")
    if limit_el is not None:
        what = f"joint {name!r} limit"
        lower = _floats(limit_el.get("lower"), 1, f"{what} lower", (0.0,))[0]
        upper = _floats(limit_el.get("upper"), 1, f"{what} upper", (0.0,))[0]
        velocity = _floats(limit_el.get("velocity"), 1, f"{what} velocity")[0]
        effort = _floats(limit_el.get("effort"), 1, f"{what} effort")[0]
        if jtype in ("revolute", "prismatic") and lower > upper:
            raise ValueError(f"joint {name!r}: limit lower {lower} > upper {upper}")
        if velocity < 0.0 or effort < 0.0:
            raise ValueError(f"joint {name!r}: negative velocity or effort limit")
        limits = JointLimits(lower, upper, velocity, effort)
    elif jtype in ("revolute", "prismatic"):
        raise ValueError(f"joint {name!r}: a {jtype} joint needs a <limit>")
    return Joint(name, jtype, links["parent"], links["child"], origin, axis, limits)


class UrdfModel:
    """The kinematic tree of a URDF robot.

    Build with ``UrdfModel.from_file(path)`` or ``UrdfModel.from_string(xml)``.
    ``links`` and ``joints`` are dicts by name (in file order); ``root`` is the
    one link without a parent. ``transform(a, b, joint_positions)`` composes
    the joint origins (and motions) along the tree path between any two links.
    """

    def __init__(self, name: str, links: Sequence[Link], joints: Sequence[Joint]):
        self.name = name
        self.links: Dict[str, Link] = {}
        for link in links:
            if link.name in self.links:
                raise ValueError(f"duplicate link {link.name!r}")
            self.links[link.name] = link
        self.joints: Dict[str, Joint] = {}
        self._parent_joint: Dict[str, Joint] = {}
        for joint in joints:
            if joint.name in self.joints:
                raise ValueError(f"duplicate joint {joint.name!r}")
            for role, link_name in (("parent", joint.parent), ("child", joint.child)):
                if link_name not in self.links:
                    raise ValueError(f"joint {joint.name!r}: {role} link {link_name!r} is not defined")
            if joint.parent == joint.child:
                raise ValueError(f"joint {joint.name!r} connects link {joint.child!r} to itself")
            if joint.child in self._parent_joint:
                other = self._parent_joint[joint.child].name
                raise ValueError(f"link {joint.child!r} has two parent joints: {other!r} and {joint.name!r}")
            self.joints[joint.name] = joint
            self._parent_joint[joint.child] = joint
        if not self.links:
            raise ValueError("the URDF has no links")
        roots = [n for n in self.links if n not in self._parent_joint]
        # With one parent per link, a link that never reaches a root lies on a cycle.
        for start in self.links:
            seen = set()
            node = start
            while node in self._parent_joint:
                if node in seen:
                    raise ValueError(f"the joints form a cycle through link {node!r}")
                seen.add(node)
                node = self._parent_joint[node].parent
        if len(roots) != 1:
            raise ValueError(f"the URDF must have exactly one root link, found {roots}")
        self.root: str = roots[0]

    # ------------------------------------------------------------------ input
    @classmethod
    def from_string(cls, xml: str) -> "UrdfModel":
        """Parse URDF XML text."""
        if not isinstance(xml, str) or not xml.strip():
            raise ValueError("URDF text is empty")
        try:
            root = ET.fromstring(xml)
        except ET.ParseError as exc:
            raise ValueError(f"URDF is not well-formed XML: {exc}") from None
        if root.tag != "robot":
            raise ValueError(f"URDF root element must be <robot>, got <{root.tag}>")
        links = [_parse_link(el) for el in root.findall("link")]
        joints = [_parse_joint(el) for el in root.findall("joint")]
        return cls(root.get("name", ""), links, joints)

    @classmethod
    def from_file(cls, path: Union[str, pathlib.Path]) -> "UrdfModel":
        """Read a URDF file."""
        path = pathlib.Path(path)
        if not path.is_file():
            raise ValueError(f"URDF file {str(path)!r} does not exist")
        try:
            return cls.from_string(path.read_text())
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None

    # ---------------------------------------------------------------- queries
    def parent_joint(self, link: str) -> Optional[Joint]:
        """The joint whose child is ``link`` (None for the root)."""
        self._check_link(link)
        return self._parent_joint.get(link)

    def movable_joints(self) -> List[Joint]:
        """All joints that are not fixed, in file order."""
        return [j for j in self.joints.values() if not j.is_fixed]

    def joint_limits(self, joint: str) -> JointLimits:
        """The <limit> of a joint; ValueError if it has none."""
        if joint not in self.joints:
            raise ValueError(f"unknown joint {joint!r}")
        limits = self.joints[joint].limits
        if limits is None:
            raise ValueError(f"joint {joint!r} has no <limit>")
        return limits

    def chain(self, parent_link: str, child_link: str) -> Tuple[List[Joint], List[Joint]]:
        """The tree path between two links as (up, down) joint lists.

        ``up`` are the joints climbing from parent_link to the common
        ancestor (nearest first), ``down`` the joints descending from the
        common ancestor to child_link (in order).
        """
        self._check_link(parent_link)
        self._check_link(child_link)
        up_a = self._path_to_root(parent_link)
        up_b = self._path_to_root(child_link)
        # Drop the shared part above the lowest common ancestor.
        while up_a and up_b and up_a[-1] is up_b[-1]:
            up_a.pop()
            up_b.pop()
        return up_a, list(reversed(up_b))

    def transform(
        self,
        parent_link: str,
        child_link: str,
        joint_positions: Optional[Mapping[str, float]] = None,
    ) -> np.ndarray:
        """T_parent_child (4x4): the pose of child_link in parent_link.

        Every non-fixed joint on the path needs a position in
        ``joint_positions`` (joint name -> rad or m); ValueError otherwise.
        """
        positions = dict(joint_positions or {})
        up, down = self.chain(parent_link, child_link)
        t_anc_parent = np.eye(4)
        for joint in reversed(up):
            t_anc_parent = t_anc_parent @ joint.transform(self._position(joint, positions, parent_link, child_link))
        t_anc_child = np.eye(4)
        for joint in down:
            t_anc_child = t_anc_child @ joint.transform(self._position(joint, positions, parent_link, child_link))
        return invert(t_anc_parent) @ t_anc_child

    def fixed_transform(self, parent_link: str, child_link: str) -> np.ndarray:
        """T_parent_child through fixed joints only; ValueError when the path
        crosses a movable joint (use ``transform`` with joint positions)."""
        return self.transform(parent_link, child_link, None)

    # --------------------------------------------------------------- helpers
    def _check_link(self, link: str) -> None:
        if link not in self.links:
            raise ValueError(f"unknown link {link!r}")

    def _path_to_root(self, link: str) -> List[Joint]:
        path = []
        while link in self._parent_joint:
            joint = self._parent_joint[link]
            path.append(joint)
            link = joint.parent
        return path

    @staticmethod
    def _position(joint: Joint, positions: Mapping[str, float], a: str, b: str) -> float:
        if joint.is_fixed:
            return 0.0
        if joint.name not in positions:
            raise ValueError(
                f"the path {a!r} -> {b!r} crosses {joint.type} joint {joint.name!r}; give its position in joint_positions"
            )
        value = float(positions[joint.name])
        if not math.isfinite(value):
            raise ValueError(f"joint position of {joint.name!r} is not finite: {value}")
        return value
