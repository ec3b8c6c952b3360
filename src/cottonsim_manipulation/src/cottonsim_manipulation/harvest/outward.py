"""The outward direction of a boll and the stem it hangs from, estimated from the targets (base_link, metres).

The robot sees neither; harvest.harvester's module docstring says how each model
(``config.outward``: 'row_grid', 'plant', 'lateral', 'radial') works and how well.
``config`` is a harvest.harvester.HarvestConfig (outward, row_offset_m,
plant_half_spacing_m, grid_window_m).
"""
from __future__ import annotations

import math

import numpy as np

OUTWARD_MODELS = ("row_grid", "plant", "lateral", "radial")


def estimate_stem(boll_base_m, targets_base_m, config) -> np.ndarray:
    """The boll's stem (x, y) in base_link [m] as the 'plant' or 'row_grid' model estimates it: on the row
    line ``row_offset_m`` to the boll's side; along the row at the centre of its plant (a mean shift over the
    targets (N, 3) on that side within ``plant_half_spacing_m``, from the boll's own x) or at the nearest
    point of the regular stem grid fitted to them (harvest.harvester's docstring)."""
    p = np.asarray(boll_base_m, dtype=float).reshape(3)
    side = 1.0 if p[1] >= 0.0 else -1.0
    others = np.asarray(targets_base_m, dtype=float).reshape(-1, 3)
    along = others[others[:, 1] * side >= 0.0, 0]
    if config.outward == "row_grid":
        return np.array([_grid_point(p[0], along, 2.0 * config.plant_half_spacing_m, config.grid_window_m),
                         side * config.row_offset_m])
    x = p[0]
    for _ in range(20):
        window = along[np.abs(along - x) <= config.plant_half_spacing_m]
        if not len(window) or abs(window.mean() - x) < 1e-4:
            break
        x = float(window.mean())
    return np.array([x, side * config.row_offset_m])


def _grid_point(x_m: float, along_m: np.ndarray, spacing_m: float, window_m: float) -> float:
    """The point nearest x_m of the grid of period spacing_m whose phase is the circular mean of the
    positions along_m within window_m of x_m (x_m itself when there are none)."""
    near = along_m[np.abs(along_m - x_m) <= window_m]
    if not len(near):
        return float(x_m)
    k = 2.0 * math.pi / spacing_m
    phase_m = math.atan2(float(np.mean(np.sin(k * near))), float(np.mean(np.cos(k * near)))) / k
    return phase_m + round((x_m - phase_m) / spacing_m) * spacing_m


def estimate_outward(boll_base_m, targets_base_m, shoulder_base_m, config) -> np.ndarray:
    """The boll's outward direction (unit, horizontal, base_link) as config.outward estimates it.

    boll_base_m: the boll (3,); targets_base_m: every target (N, 3), for the plant's centre; shoulder_base_m:
    the arm's shoulder (3,); all in base_link [m]."""
    p = np.asarray(boll_base_m, dtype=float).reshape(3)
    side = 1.0 if p[1] >= 0.0 else -1.0
    lateral = np.array([0.0, -side, 0.0])
    if config.outward == "lateral":
        return lateral
    if config.outward == "radial":
        d = np.asarray(shoulder_base_m, dtype=float).reshape(3) - p
        d[2] = 0.0
    else:
        stem = estimate_stem(p, targets_base_m, config)
        d = np.array([p[0] - stem[0], p[1] - stem[1], 0.0])
    n = float(np.linalg.norm(d))
    return d / n if n > 1e-9 else lateral
