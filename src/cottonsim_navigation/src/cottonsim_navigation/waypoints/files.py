"""Readers for waypoint files (GPS and map routes).

GPS waypoints: plain text with one "lat lon" per line (the original's
waypoints.txt; commas also separate), '#' comments and blank lines allowed;
or YAML: a list of {lat, lon} / {latitude, longitude} (optionally under a
top-level 'waypoints' key).

Map waypoints: CSV with a header containing x, y and yaw_rad (optional
label; the original's map CSV is ``label,x,y,yaw_rad``), or plain "x y yaw"
lines (yaw optional, 0), or YAML: a list of {x, y, yaw[_rad], label}.

Every problem raises :class:`WaypointFileError` naming the file and, where
there is one, the line number.
"""
from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence, Tuple

from cottonsim_common.config.yaml_files import DuplicateKeyError, YamlSyntaxError, load_yaml_text


class WaypointFileError(ValueError):
    """A waypoint file that cannot be read; message holds path and line."""

    def __init__(self, path: str, message: str, line: Optional[int] = None):
        self.path = str(path)
        self.line = line
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")


@dataclass(frozen=True)
class GpsWaypoint:
    """One GPS waypoint [deg]."""

    lat: float
    lon: float
    label: str = ""


@dataclass(frozen=True)
class MapWaypoint:
    """One map-frame waypoint: position [m], heading [rad]."""

    x_m: float
    y_m: float
    yaw_rad: float = 0.0
    label: str = ""


def _number(path, line, text, what) -> float:
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise WaypointFileError(path, f"{what} is not a number: {text!r}", line) from None
    if not math.isfinite(v):
        raise WaypointFileError(path, f"{what} is not finite: {text!r}", line)
    return v


def _check_gps(path, line, lat, lon) -> None:
    if not -90.0 <= lat <= 90.0:
        raise WaypointFileError(path, f"latitude {lat} outside [-90, 90]", line)
    if not -180.0 <= lon <= 180.0:
        raise WaypointFileError(path, f"longitude {lon} outside [-180, 180]", line)


def _read_text(path) -> str:
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise WaypointFileError(path, "file not found")
    try:
        with open(path, "r", encoding="utf-8") as f:
            return f.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise WaypointFileError(path, f"cannot read: {exc}") from None


def _is_yaml(path) -> bool:
    return os.fspath(path).lower().endswith((".yaml", ".yml"))


def _yaml_items(path, text) -> list:
    try:
        data = load_yaml_text(text, source=os.fspath(path))
    except DuplicateKeyError as exc:
        raise WaypointFileError(path, f"key {exc.key!r} is given twice (lines {exc.first_line} and "
                                      f"{exc.second_line})", exc.second_line) from None
    except YamlSyntaxError as exc:
        raise WaypointFileError(path, f"invalid YAML: {exc.problem}", exc.line) from None
    if isinstance(data, dict) and "waypoints" in data:
        data = data["waypoints"]
    if data is None:
        raise WaypointFileError(path, "no waypoints in file")
    if not isinstance(data, list):
        raise WaypointFileError(path, "YAML must be a list of waypoints (or have a 'waypoints' list)")
    if not data:
        raise WaypointFileError(path, "no waypoints in file")
    return data


def _split(line: str) -> List[str]:
    return line.replace(",", " ").split()


def _data_lines(text: str) -> List[Tuple[int, str]]:
    """(line number, content) of the lines that hold data: '#' comments and blank lines dropped."""
    lines = [(n, raw.split("#", 1)[0].strip()) for n, raw in enumerate(text.splitlines(), start=1)]
    return [(n, line) for n, line in lines if line]


def _yaml_waypoints(path, text: str, parse_item: Callable) -> list:
    """Each item of a YAML waypoint list as ``parse_item(item, where)`` (where: "waypoint N", 1-based)."""
    return [parse_item(item, f"waypoint {i + 1}") for i, item in enumerate(_yaml_items(path, text))]


def load_gps_waypoints(path) -> List[GpsWaypoint]:
    """Read GPS waypoints (text 'lat lon' lines or YAML); see the module docstring."""
    text = _read_text(path)
    if _is_yaml(path):
        return _yaml_waypoints(path, text, lambda item, where: _gps_waypoint_item(path, item, where))
    out: List[GpsWaypoint] = []
    for n, line in _data_lines(text):
        cols = _split(line)
        if len(cols) != 2:
            raise WaypointFileError(path, f"expected 2 columns 'lat lon', got {len(cols)}", n)
        lat = _number(path, n, cols[0], "latitude")
        lon = _number(path, n, cols[1], "longitude")
        _check_gps(path, n, lat, lon)
        out.append(GpsWaypoint(lat, lon))
    if not out:
        raise WaypointFileError(path, "no waypoints in file")
    return out


def _gps_waypoint_item(path, item, where: str) -> GpsWaypoint:
    """One YAML GPS waypoint: a mapping with lat and lon (or latitude and longitude), label optional."""
    if not isinstance(item, dict):
        raise WaypointFileError(path, f"{where} must be a mapping with lat/lon")
    lat = item.get("lat", item.get("latitude"))
    lon = item.get("lon", item.get("longitude"))
    if lat is None or lon is None:
        raise WaypointFileError(path, f"{where} needs lat and lon (or latitude and longitude)")
    lat = _number(path, None, lat, f"{where} latitude")
    lon = _number(path, None, lon, f"{where} longitude")
    try:
        _check_gps(path, None, lat, lon)
    except WaypointFileError as exc:
        raise WaypointFileError(path, f"{where}: {str(exc).split(': ', 1)[1]}") from None
    return GpsWaypoint(lat, lon, str(item.get("label", "")))


def _map_waypoint_item(path, item, where: str) -> MapWaypoint:
    """One YAML map waypoint: a mapping with x and y, yaw_rad (or yaw) and label optional."""
    if not isinstance(item, dict) or "x" not in item or "y" not in item:
        raise WaypointFileError(path, f"{where} must be a mapping with x and y")
    yaw = item.get("yaw_rad", item.get("yaw", 0.0))
    return MapWaypoint(_number(path, None, item["x"], f"{where} x"), _number(path, None, item["y"], f"{where} y"),
                       _number(path, None, yaw, f"{where} yaw"), str(item.get("label", "")))


def load_map_waypoints(path) -> List[MapWaypoint]:
    """Read map-frame waypoints (CSV with header, 'x y yaw' lines, or YAML)."""
    text = _read_text(path)
    if _is_yaml(path):
        return _yaml_waypoints(path, text, lambda item, where: _map_waypoint_item(path, item, where))
    out: List[MapWaypoint] = []
    lines = _data_lines(text)
    if not lines:
        raise WaypointFileError(path, "no waypoints in file")
    first_n, first = lines[0]
    header = [h.strip().lower() for h in first.split(",")]
    if "x" in header and "y" in header:
        ix, iy = header.index("x"), header.index("y")
        iyaw = header.index("yaw_rad") if "yaw_rad" in header else (header.index("yaw") if "yaw" in header else None)
        ilab = header.index("label") if "label" in header else None
        for n, l in lines[1:]:
            cols = next(csv.reader(io.StringIO(l)))
            if len(cols) != len(header):
                raise WaypointFileError(path, f"expected {len(header)} columns ({','.join(header)}), "
                                              f"got {len(cols)}", n)
            out.append(MapWaypoint(_number(path, n, cols[ix], "x"), _number(path, n, cols[iy], "y"),
                                   _number(path, n, cols[iyaw], "yaw") if iyaw is not None else 0.0,
                                   cols[ilab].strip() if ilab is not None else ""))
    else:
        for n, l in lines:
            cols = _split(l)
            if len(cols) not in (2, 3):
                raise WaypointFileError(path, f"expected 'x y [yaw]', got {len(cols)} columns", n)
            out.append(MapWaypoint(_number(path, n, cols[0], "x"), _number(path, n, cols[1], "y"),
                                   _number(path, n, cols[2], "yaw") if len(cols) == 3 else 0.0))
    if not out:
        raise WaypointFileError(path, "no waypoints in file")
    return out


def load_gps_lanes(path) -> List[tuple]:
    """Read lane centre lines: 'lat lon lat lon' per line (start and end of one lane) [deg].

    '#' comments and blank lines allowed. Returns a list of (GpsWaypoint,
    GpsWaypoint) pairs; a line with another column count, a bad number or two
    equal ends raises WaypointFileError naming the line.
    """
    text = _read_text(path)
    out: List[tuple] = []
    for n, line in _data_lines(text):
        cols = _split(line)
        if len(cols) != 4:
            raise WaypointFileError(path, f"expected 4 columns 'lat lon lat lon' (a lane's two ends), "
                                          f"got {len(cols)}", n)
        vals = [_number(path, n, c, what) for c, what in zip(cols, ("start latitude", "start longitude",
                                                                  "end latitude", "end longitude"))]
        _check_gps(path, n, vals[0], vals[1])
        _check_gps(path, n, vals[2], vals[3])
        if vals[0] == vals[2] and vals[1] == vals[3]:
            raise WaypointFileError(path, "the lane's two ends are the same point", n)
        out.append((GpsWaypoint(vals[0], vals[1]), GpsWaypoint(vals[2], vals[3])))
    if not out:
        raise WaypointFileError(path, "no lanes in file")
    return out


def save_gps_lanes(path, lanes: Sequence[tuple], comment: str = "") -> None:
    """Write lanes as 'lat lon lat lon' lines (see load_gps_lanes), with an optional header comment."""
    with open(path, "w", encoding="utf-8") as f:
        for line in comment.splitlines():
            f.write(f"# {line}\n")
        for a, b in lanes:
            f.write(f"{a.lat!r} {a.lon!r} {b.lat!r} {b.lon!r}\n")
