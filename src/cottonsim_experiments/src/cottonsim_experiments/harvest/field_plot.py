"""The harvest's field plot: every open boll seen from above, picked / missed (why) / not reachable.

``plot_harvest_field`` draws the plants (their canopy as a circle round the stem), the lanes
of the route and each boll at its position from a ``BollOutcome`` (harvest/metrics.py, with
position_m): picked (in the bin), missed with the reason (the pick's, or 'not detected' /
'not attempted'), not reachable from the route. A region (x0, x1, y0, y1) [m, world] zooms in,
e.g. on the row a run harvested. Writes a PNG.
"""
from __future__ import annotations

import collections
import pathlib
from typing import Optional, Sequence, Tuple, Union

from cottonsim_experiments.harvest.metrics import BollOutcome

_MISS_STYLE = {          # reason -> (colour, marker)
    "not detected": ("#ff7f0e", "v"), "not attempted": ("#d62728", "s"), "unreachable": ("#9467bd", "D"),
    "ik_failed": ("#8c564b", "P"), "collision": ("#e377c2", "X"), "aborted": ("#bcbd22", "<"),
    "capture_missed": ("#17becf", ">"), "lost": ("#1f77b4", "^"), "timeout": ("#7f7f7f", "h"),
    "dropped": ("#000000", "*"),
}


def outcome_class(o: BollOutcome) -> str:
    """'picked', 'missed: <why>' or 'not reachable'."""
    if o.in_bin:
        return "picked"
    if not o.reachable:
        return "not reachable"
    if o.reason:
        return f"missed: {o.reason}"
    return "missed: not attempted" if o.detected else "missed: not detected"


def plot_harvest_field(path: Union[str, pathlib.Path], outcomes: Sequence[BollOutcome], plant_xy_m,
                       plant_radius_m: float = 0.33, lanes: Sequence = (), title: str = "",
                       region: Optional[Tuple[float, float, float, float]] = None) -> pathlib.Path:
    """Write the field plot (PNG) to path; outcomes need position_m. Returns the path."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    missing = [o.boll_id for o in outcomes if o.position_m is None]
    if missing:
        raise ValueError(f"the field plot needs every boll's position_m; missing for bolls {missing[:10]}")
    path = pathlib.Path(path)
    xs = [float(o.position_m[0]) for o in outcomes]
    ys = [float(o.position_m[1]) for o in outcomes]
    if region is None:
        pts = [(float(x), float(y)) for x, y in plant_xy_m] + list(zip(xs, ys))
        if not pts:
            raise ValueError("nothing to plot: no plants and no bolls")
        pad = 0.6
        region = (min(p[0] for p in pts) - pad, max(p[0] for p in pts) + pad,
                  min(p[1] for p in pts) - pad, max(p[1] for p in pts) + pad)
    x0, x1, y0, y1 = region
    if not (x1 > x0 and y1 > y0):
        raise ValueError(f"region must be (x0, x1, y0, y1) with x1 > x0 and y1 > y0, got {region!r}")
    scale = 9.0 / max(x1 - x0, y1 - y0)
    fig, ax = plt.subplots(figsize=(max(8.0, (x1 - x0) * scale + 4.0), max(5.0, (y1 - y0) * scale + 1.2)))
    for x, y in plant_xy_m:
        ax.add_patch(Circle((x, y), plant_radius_m, facecolor="#cfe8c4", edgecolor="#8fbf80", lw=0.6, zorder=1))
    for lane in lanes:
        ax.plot([lane.x_m, lane.x_m], [lane.y_start_m, lane.y_end_m], ls="--", color="#999999", lw=0.8, zorder=2)
    classes = collections.defaultdict(list)
    for o, x, y in zip(outcomes, xs, ys):
        classes[outcome_class(o)].append((x, y))
    marker_size = max(6.0, min(40.0, 1600.0 / max(1.0, (x1 - x0) * (y1 - y0))))

    def draw(name, colour, marker, size, z):
        pts = classes.get(name, [])
        if pts:
            edge = {"edgecolors": "white"} if marker == "o" else {}
            ax.scatter([p[0] for p in pts], [p[1] for p in pts], s=size, c=colour, marker=marker, zorder=z,
                       linewidths=0.5, label=f"{name} ({len(pts)})", **edge)

    draw("picked", "#2ca02c", "o", marker_size, 4)
    draw("not reachable", "#333333", "x", marker_size * 1.6, 6)
    for name in sorted(c for c in classes if c.startswith("missed: ")):
        colour, marker = _MISS_STYLE.get(name[len("missed: "):], ("#d62728", "o"))
        draw(name, colour, marker, marker_size * 1.6, 5)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("world x [m]")
    ax.set_ylabel("world y [m] (rows run along y)")
    ax.set_title(title or f"harvest: {len(classes.get('picked', []))} of {len(outcomes)} open bolls picked",
                 fontsize=10, loc="left")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False, title="bolls (top view)")
    ax.grid(True, lw=0.3, alpha=0.5)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path
