"""A tiny URDF writer for make_urdf.py: shapes, inertias, links and joints as indented XML.

Numbers are written with up to 10 significant digits (never '-0'), so the
generated file is deterministic and diffs stay readable.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import List, Mapping, Optional, Sequence, Tuple

Vec3 = Tuple[float, float, float]


# Links that are only frames (optical frames, tool0, ...) and the top plate
# (its mass is part of the chassis mass) get this negligible inertial: URDF
# allows none, but pybullet would then give each such link 1 kg.
FRAME_MASS_KG = 0.001
FRAME_INERTIA_KGM2 = 1e-9


@dataclass(frozen=True)
class ArmJoint:
    """A movable joint's limits: position [rad], velocity [rad/s], effort [N m]."""

    name: str
    lower_rad: float
    upper_rad: float
    velocity_rad_s: float
    effort_nm: float



# ---------------------------------------------------------------------------
# A tiny URDF writer
# ---------------------------------------------------------------------------
def fmt(value: float) -> str:
    """A number as URDF text: up to 10 significant digits, never '-0'."""
    text = f"{value:.10g}"
    return "0" if text in ("-0", "0") else text


def fmt3(values: Sequence[float]) -> str:
    return " ".join(fmt(v) for v in values)


@dataclass(frozen=True)
class Shape:
    """A visual/collision primitive with its origin in the link frame.

    kind 'box' (size = full extents x y z), 'cylinder' (radius, length; axis
    along z of its origin) or 'sphere' (radius,).
    """

    kind: str
    size: Tuple[float, ...]
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)
    material: str = "dark_grey"


def box(size: Vec3, xyz: Vec3 = (0, 0, 0), material: str = "dark_grey", rpy: Vec3 = (0, 0, 0)) -> Shape:
    return Shape("box", tuple(size), tuple(xyz), tuple(rpy), material)


def cyl(radius: float, length: float, xyz: Vec3 = (0, 0, 0), rpy: Vec3 = (0, 0, 0), material: str = "dark_grey") -> Shape:
    return Shape("cylinder", (radius, length), tuple(xyz), tuple(rpy), material)


def cyl_z(radius: float, z0: float, z1: float, x: float = 0.0, y: float = 0.0, material: str = "dark_grey") -> Shape:
    """A cylinder along z spanning z0..z1 [m]."""
    return cyl(radius, z1 - z0, (x, y, (z0 + z1) / 2.0), material=material)


@dataclass(frozen=True)
class Inertial:
    """Mass [kg], centre of mass [m] and inertia (ixx, iyy, izz) [kg m^2]."""

    mass_kg: float
    com_m: Vec3
    diag_kgm2: Vec3


def box_inertia(mass_kg: float, size: Vec3, com: Vec3 = (0, 0, 0)) -> Inertial:
    x, y, z = size
    k = mass_kg / 12.0
    return Inertial(mass_kg, com, (k * (y * y + z * z), k * (x * x + z * z), k * (x * x + y * y)))


def cylinder_inertia(mass_kg: float, radius: float, length: float, axis: str = "z", com: Vec3 = (0, 0, 0)) -> Inertial:
    """Solid cylinder; axis names the link axis the cylinder lies along."""
    along = 0.5 * mass_kg * radius * radius
    across = mass_kg * (3.0 * radius * radius + length * length) / 12.0
    diag = {"x": (along, across, across), "y": (across, along, across), "z": (across, across, along)}[axis]
    return Inertial(mass_kg, com, diag)


class UrdfWriter:
    """Collects links and joints and writes them as indented URDF XML."""

    def __init__(self, robot_name: str, materials: Mapping[str, Tuple[float, float, float, float]]):
        self.root = ET.Element("robot", name=robot_name)
        self.link_names: List[str] = []
        for name, rgba in materials.items():
            mat = ET.SubElement(self.root, "material", name=name)
            ET.SubElement(mat, "color", rgba=fmt3(rgba))

    def add_material(self, name: str, rgba: Tuple[float, float, float, float]) -> str:
        """Declare one more colour (before the links that use it are written); returns its name."""
        mat = ET.Element("material", name=name)
        ET.SubElement(mat, "color", rgba=fmt3(rgba))
        index = sum(1 for el in self.root if el.tag == "material")
        self.root.insert(index, mat)
        return name

    def comment(self, text: str) -> None:
        self.root.append(ET.Comment(f" {text} "))

    @staticmethod
    def _origin(parent: ET.Element, xyz: Sequence[float], rpy: Sequence[float]) -> None:
        ET.SubElement(parent, "origin", xyz=fmt3(xyz), rpy=fmt3(rpy))

    @staticmethod
    def _geometry(parent: ET.Element, shape: Shape) -> None:
        geo = ET.SubElement(parent, "geometry")
        if shape.kind == "box":
            ET.SubElement(geo, "box", size=fmt3(shape.size))
        elif shape.kind == "cylinder":
            ET.SubElement(geo, "cylinder", radius=fmt(shape.size[0]), length=fmt(shape.size[1]))
        elif shape.kind == "sphere":
            ET.SubElement(geo, "sphere", radius=fmt(shape.size[0]))
        else:
            raise ValueError(f"unknown shape kind {shape.kind!r}")

    def link(
        self,
        name: str,
        visuals: Sequence[Shape] = (),
        collisions: Sequence[Shape] = (),
        inertial: Optional[Inertial] = None,
        massless: bool = False,
    ) -> None:
        """Add a link; ``massless`` leaves out <inertial> (only for the root: KDL rejects a root with inertia)."""
        if name in self.link_names:
            raise ValueError(f"duplicate link {name!r}")
        self.link_names.append(name)
        el = ET.SubElement(self.root, "link", name=name)
        for shape in visuals:
            vis = ET.SubElement(el, "visual")
            self._origin(vis, shape.xyz, shape.rpy)
            self._geometry(vis, shape)
            ET.SubElement(vis, "material", name=shape.material)
        for shape in collisions:
            col = ET.SubElement(el, "collision")
            self._origin(col, shape.xyz, shape.rpy)
            self._geometry(col, shape)
        if massless:
            return
        if inertial is None:
            inertial = Inertial(FRAME_MASS_KG, (0.0, 0.0, 0.0), (FRAME_INERTIA_KGM2,) * 3)
        ine = ET.SubElement(el, "inertial")
        self._origin(ine, inertial.com_m, (0, 0, 0))
        ET.SubElement(ine, "mass", value=fmt(inertial.mass_kg))
        ixx, iyy, izz = inertial.diag_kgm2
        ET.SubElement(ine, "inertia", ixx=fmt(ixx), ixy="0", ixz="0", iyy=fmt(iyy), iyz="0", izz=fmt(izz))

    def joint(
        self,
        name: str,
        kind: str,
        parent: str,
        child: str,
        xyz: Sequence[float] = (0, 0, 0),
        rpy: Sequence[float] = (0, 0, 0),
        axis: Optional[Vec3] = None,
        limit: Optional[ArmJoint] = None,
    ) -> None:
        el = ET.SubElement(self.root, "joint", name=name, type=kind)
        ET.SubElement(el, "parent", link=parent)
        ET.SubElement(el, "child", link=child)
        self._origin(el, xyz, rpy)
        if axis is not None:
            ET.SubElement(el, "axis", xyz=fmt3(axis))
        if limit is not None:
            ET.SubElement(
                el,
                "limit",
                lower=fmt(limit.lower_rad),
                upper=fmt(limit.upper_rad),
                effort=fmt(limit.effort_nm),
                velocity=fmt(limit.velocity_rad_s),
            )

    def to_string(self) -> str:
        ET.indent(self.root, space="  ")
        body = ET.tostring(self.root, encoding="unicode")
        header = (
            '<?xml version="1.0"?>\n'
            "<!-- GENERATED by src/cottonsim_description/scripts/make_urdf.py; do not edit by hand. -->\n"
        )
        return header + body + "\n"

