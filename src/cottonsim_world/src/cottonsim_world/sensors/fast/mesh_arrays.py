"""A plant model as flat mesh arrays, and the parts (connected components) of such a mesh.

The five arrays (vertices, faces int32, face semantic, face rgb, face unit
normal) are what the numba camera draws; the levels of detail
(``level_of_detail``) rebuild a model part by part from them. Frames:
plant-local as in ``farm.model`` [m].
"""
from __future__ import annotations

from typing import Tuple

import numpy as np

from cottonsim_world.farm.model import PlantModel


def model_arrays(model: PlantModel) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One model's meshes merged: vertices, faces, face semantic, face rgb, face unit normal."""
    verts, faces, sem, rgb = [], [], [], []
    offset = 0
    for mesh in model.meshes.values():
        v = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
        if len(f) == 0:
            continue
        verts.append(v)
        faces.append(f + offset)
        sem.append(np.full(len(f), int(mesh.semantic), dtype=np.uint8))
        rgb.append(np.tile(np.asarray(mesh.rgba[:3], dtype=np.float64), (len(f), 1)))
        offset += len(v)
    if not faces:
        return (np.zeros((0, 3)), np.zeros((0, 3), np.int32), np.zeros(0, np.uint8), np.zeros((0, 3)),
                np.zeros((0, 3)))
    v = np.concatenate(verts)
    f = np.concatenate(faces)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 0.0, n / np.maximum(length, 1e-300), 0.0)
    return v, f.astype(np.int32), np.concatenate(sem), np.concatenate(rgb), n


def with_normals(v: np.ndarray, f: np.ndarray, sem: np.ndarray, rgb: np.ndarray) -> Tuple[np.ndarray, ...]:
    """(vertices, faces int32, semantic, rgb, unit face normals) of a mesh."""
    nrm = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.where(length > 0.0, nrm / np.maximum(length, 1e-300), 0.0)
    return v, f.astype(np.int32), sem, rgb, nrm


def mesh_components(v: np.ndarray, f: np.ndarray) -> Tuple[int, np.ndarray]:
    """Connected components of a mesh: (count, part label per face)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(v)
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    n_parts, label = connected_components(coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)),
                                          directed=False)
    return n_parts, label[f[:, 0]]


def split_parts(v: np.ndarray, f: np.ndarray):
    """Each connected part of a mesh, in label order: (its face indices, its vertices, its faces indexing
    those vertices, its surface area [m^2])."""
    n_parts, face_part = mesh_components(v, f)
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    face_area = 0.5 * np.linalg.norm(cross, axis=1)
    for part in range(n_parts):
        fi = np.nonzero(face_part == part)[0]
        if len(fi) == 0:
            continue
        vi = np.unique(f[fi])
        remap = np.full(len(v), -1, dtype=np.int64)
        remap[vi] = np.arange(len(vi))
        yield fi, v[vi], remap[f[fi]], float(face_area[fi].sum())


def assemble_parts(parts, sem: np.ndarray, rgb: np.ndarray) -> Tuple[np.ndarray, ...]:
    """One model from (vertices, faces, first face of the source part) per part: the five arrays of
    ``model_arrays``, each part with the semantic class and base colour of its source part's first face."""
    out_v, out_f, out_sem, out_rgb = [], [], [], []
    count = 0
    for pv, pf, face0 in parts:
        out_v.append(pv)
        out_f.append(pf + count)
        out_sem.append(np.full(len(pf), sem[face0], dtype=np.uint8))
        out_rgb.append(np.tile(rgb[face0], (len(pf), 1)))
        count += len(pv)
    return with_normals(np.concatenate(out_v), np.concatenate(out_f), np.concatenate(out_sem),
                         np.concatenate(out_rgb))


def pair_reversed_faces(faces: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Faces to draw and, per drawn face, the index of its reverse-wound twin (-1 if none)."""
    if len(faces) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    # a cyclic rotation that starts at the smallest index identifies a winding; its reverse is the twin
    rot = np.argmin(faces, axis=1)
    idx = np.arange(len(faces))
    fwd = np.stack([faces[idx, rot], faces[idx, (rot + 1) % 3], faces[idx, (rot + 2) % 3]], axis=1)
    rev = fwd[:, [0, 2, 1]]
    lookup = {tuple(f): i for i, f in enumerate(fwd.tolist())}
    first, twin, used = [], [], np.zeros(len(faces), bool)
    for i in range(len(faces)):
        if used[i]:
            continue
        j = lookup.get(tuple(rev[i].tolist()), -1)
        if j >= 0 and (used[j] or j == i):
            j = -1
        used[i] = True
        if j >= 0:
            used[j] = True
        first.append(i)
        twin.append(j)
    return np.array(first, np.int64), np.array(twin, np.int64)


def convex_hull_area(points: np.ndarray) -> float:
    """Surface area of the convex hull of 3-D points [m^2]; 0 if they are (nearly) coplanar or too few."""
    from scipy.spatial import ConvexHull, QhullError

    if len(points) < 4:
        return 0.0
    try:
        return float(ConvexHull(points).area)
    except (QhullError, ValueError):
        return 0.0


def wind_outward(corners: np.ndarray, faces: np.ndarray, centre: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """(corners, faces) with every face of a closed proxy around ``centre`` counter-clockwise seen from outside."""
    nrm = np.cross(corners[faces[:, 1]] - corners[faces[:, 0]], corners[faces[:, 2]] - corners[faces[:, 0]])
    outward = np.einsum("ij,ij->i", nrm, corners[faces].mean(axis=1) - centre) > 0.0
    return corners, np.where(outward[:, None], faces, faces[:, ::-1])
