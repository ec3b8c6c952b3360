"""The ODE bodies and geoms of the world: the plants' static collision geoms and the Husky.

Plants are static geoms (no body) placed from each plant model's collision
primitives; the Husky is five bodies, a chassis of two boxes and four
cylinder wheels on hinge joints whose velocity motors the world drives.
Quaternions here are (w, x, y, z), the order ODE takes them in.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, List, Sequence, Tuple

import numpy as np

from ..farm.model import Plant, Primitive
from .husky_params import WHEEL_NAMES, HuskyParams
from .ode_library import CAT_GROUND, CAT_PLANT, CAT_ROBOT, PARAM_FMAX, PARAM_VEL, ode

STATIC_SHAPE_SIZES = {"box": 3, "cylinder": 2, "capsule": 2, "sphere": 1}   # shape -> number of size values


def _quat_mul_wxyz(a: Sequence[float], b: Sequence[float]) -> Tuple[float, float, float, float]:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def yaw_wxyz(yaw: float) -> Tuple[float, float, float, float]:
    return (math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0))


def finite_tuple(values: Iterable[float], n: int, what: str) -> Tuple[float, ...]:
    out = tuple(float(v) for v in values)
    if len(out) != n or not all(math.isfinite(v) for v in out):
        raise ValueError(f"{what} must be {n} finite numbers, got {out!r}")
    return out


def plant_primitives_in_world(plant: Plant) -> List[Primitive]:
    """The plant model's collision primitives placed at the plant's pose (world frame)."""
    for name in ("x_m", "y_m", "yaw_rad"):
        if not math.isfinite(getattr(plant, name)):
            raise ValueError(f"plant {plant.plant_id}: {name} is not finite")
    q_yaw = yaw_wxyz(plant.yaw_rad)
    c, s = math.cos(plant.yaw_rad), math.sin(plant.yaw_rad)
    world_prims = []
    for prim in plant.model.collision:
        px, py, pz = finite_tuple(prim.position, 3, f"plant {plant.plant_id} primitive {prim.name!r} position")
        qx, qy, qz, qw = finite_tuple(prim.orientation, 4,
                                      f"plant {plant.plant_id} primitive {prim.name!r} orientation")
        qw_, qx_, qy_, qz_ = _quat_mul_wxyz(q_yaw, (qw, qx, qy, qz))
        world_prims.append(Primitive(
            shape=prim.shape,
            position=(plant.x_m + c * px - s * py, plant.y_m + s * px + c * py, pz),
            orientation=(qx_, qy_, qz_, qw_), size=prim.size, name=prim.name))
    return world_prims


def static_geom(space, plant_id: int, prim: Primitive):
    """A static ODE geom in ``space`` for one primitive (world frame) of plant ``plant_id``.

    Raises ValueError naming the plant and primitive for a non-finite pose, a
    zero quaternion, an unknown shape or sizes that do not fit it.
    """
    pos = finite_tuple(prim.position, 3, f"plant {plant_id} primitive {prim.name!r} position")
    qx, qy, qz, qw = finite_tuple(prim.orientation, 4, f"plant {plant_id} primitive {prim.name!r} orientation")
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if norm < 1e-9:
        raise ValueError(f"plant {plant_id} primitive {prim.name!r}: zero quaternion")
    size = tuple(float(v) for v in prim.size)
    if not all(math.isfinite(v) and v > 0 for v in size):
        raise ValueError(f"plant {plant_id} primitive {prim.name!r}: sizes must be finite and > 0, got {size}")
    want = STATIC_SHAPE_SIZES
    if prim.shape not in want:
        raise ValueError(f"plant {plant_id} primitive {prim.name!r}: unknown shape {prim.shape!r} "
                         f"(expected one of {sorted(want)})")
    if len(size) != want[prim.shape]:
        raise ValueError(f"plant {plant_id} primitive {prim.name!r}: a {prim.shape} needs "
                         f"{want[prim.shape]} size values, got {len(size)}")
    if prim.shape == "box":
        geom = ode.GeomBox(space, tuple(2.0 * v for v in size))
    elif prim.shape == "cylinder":
        geom = ode.GeomCylinder(space, size[0], size[1])
    elif prim.shape == "capsule":
        geom = ode.GeomCapsule(space, size[0], size[1])
    else:
        geom = ode.GeomSphere(space, size[0])
    geom.setPosition(pos)
    geom.setQuaternion((qw / norm, qx / norm, qy / norm, qz / norm))
    geom.setCategoryBits(CAT_PLANT)
    geom.setCollideBits(CAT_ROBOT)
    return geom


@dataclass
class HuskyBodies:
    """The Husky's ODE parts: chassis body, wheel bodies and hinges (WHEEL_NAMES order), every geom as
    (geom, part name, body), and com_offset_m, the chassis' centre of mass in base_link [m]."""

    chassis: object
    wheels: List[object]
    hinges: List[object]
    geoms: List[Tuple[object, str, object]]
    com_offset_m: np.ndarray


def build_husky(world, space, husky: HuskyParams, x: float, y: float, yaw: float,
                wheel_max_torque_n_m: float) -> HuskyBodies:
    """The Husky at rest on the ground with base_link at (x, y) [m], heading yaw [rad]: bodies in ``world``,
    geoms in ``space``, wheel motors at zero speed with at most ``wheel_max_torque_n_m``."""
    hp = husky
    q = yaw_wxyz(yaw)
    rot = np.array([[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    base = np.array([x, y, hp.base_link_height_m])

    chassis = ode.Body(world)
    mass = ode.Mass()
    ixx, iyy, izz = hp.chassis_inertia_kg_m2
    mass.setParameters(hp.chassis_mass_kg, 0.0, 0.0, 0.0, ixx, iyy, izz, 0.0, 0.0, 0.0)
    chassis.setMass(mass)
    com_offset = np.array([0.0, 0.0, hp.chassis_com_height_m])
    chassis.setPosition(tuple(base + rot @ com_offset))
    chassis.setQuaternion(q)
    geoms = []
    for part, centre, size in (("chassis", hp.lower_box_centre_m, hp.lower_box_size_m),
                               ("chassis", hp.upper_box_centre_m, hp.upper_box_size_m)):
        g = ode.GeomBox(space, size)
        g.setBody(chassis)
        g.setOffsetPosition(tuple(np.asarray(centre) - com_offset))
        geoms.append((g, part, chassis))

    wheels, hinges = [], []
    # GeomCylinder's axis is its local z; turn it onto the wheel axle (y).
    q_axle = (math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0)
    for name, wpos in zip(WHEEL_NAMES, hp.wheel_positions_base_link()):
        body = ode.Body(world)
        m = ode.Mass()
        m.setCylinderTotal(hp.wheel_mass_kg, 2, hp.wheel_radius_m, hp.wheel_width_m)
        body.setMass(m)
        centre = base + rot @ np.asarray(wpos)
        body.setPosition(tuple(centre))
        body.setQuaternion(q)
        g = ode.GeomCylinder(space, hp.wheel_radius_m, hp.wheel_width_m)
        g.setBody(body)
        g.setOffsetQuaternion(q_axle)
        geoms.append((g, name, body))
        hinge = ode.HingeJoint(world)
        hinge.attach(body, chassis)       # rate = wheel minus chassis: > 0 rolls forward
        hinge.setAnchor(tuple(centre))
        hinge.setAxis(tuple(rot @ np.array([0.0, 1.0, 0.0])))
        hinge.setParam(PARAM_VEL, 0.0)
        hinge.setParam(PARAM_FMAX, wheel_max_torque_n_m)
        wheels.append(body)
        hinges.append(hinge)
    for g, part, body in geoms:
        g.setCategoryBits(CAT_ROBOT)
        g.setCollideBits(CAT_GROUND | CAT_PLANT)
    return HuskyBodies(chassis, wheels, hinges, geoms, com_offset)
