"""Row centring from the sky and ground masks (the paper's Fig. 10 method).

Why: between two cotton rows the front camera sees a strip of ground running
away from the robot and, above the canopies, a strip of sky; both narrow
towards the row's vanishing point. The paper keeps the robot centred by
fitting one line to each strip and steering towards their intersection.

Method (pure function of two boolean masks, :func:`compute_row_centring`):

1. For each mask (ground, sky) find its top-most and bottom-most rows and take
   the mid-x of the mask there: the mean x of the mask's pixels in a row.
   Instead of a single row we use the ``band_rows`` first (last) rows that hold
   at least ``min_row_pixels`` pixels and take the *median* of their mid-x and
   y. Why: the extreme row of a segmentation mask is its least reliable part -
   often a few pixels of a polygon tip, a speckle or an anti-aliased edge -
   so a single row makes the point jump by tens of pixels between frames; the
   median of a few rows ignores such outliers and costs nothing.
   Strip tracing (``trace_strips``, default on; not in the paper): before
   step 1 each mask is cut down to the one strip that belongs to the robot's
   own lane: the ground is followed upwards from its bottom row (starting
   with the run of pixels under the image centre, then in each row the run
   that overlaps the previous row's run most), the sky downwards from its
   top row. Why: in the simulated farm (and in a real one) the ground and
   sky are also visible in the gaps between the plants of the neighbouring
   rows and beyond the last row of the field; the plain per-row mean then
   drifts towards the open side of the field (measured in lane 1 of the
   default farm: the intersection lay 57 px right of centre on a 320 px
   image although the robot was centred and aligned, and the closed loop
   steered the robot into a plant). With tracing the same frame gives 0 px.
2. A line through the two points of each mask, written x = a * y + b (the
   points of a mask never share a y, so the line is never horizontal).
3. Intersect the ground line and the sky line: y = (b_s - b_g) / (a_g - a_s).
   Parallel lines (|a_g - a_s| < ``parallel_tolerance``) or an intersection
   outside the image give no estimate - unless the two lines (nearly)
   coincide: a robot exactly on the row's centre line sees both lines
   vertical through the vanishing point, and their intersection is then
   undefined or far away although the answer is clearly 'straight'. So when
   the lines are less than ``coincident_tolerance_px`` apart at the horizon
   (y_h, half way between the sky's bottom and the ground's top point), the
   point on the horizon half way between them is used as the intersection.
   (The original code had no such case and divided by ~zero.)
4. Compare the intersection's x with the image centre cx = W / 2:
   ``-dead_band_px < x - cx <= dead_band_px`` -> 'straight' (the original's
   280 < x <= 360 on a 640 px image); x left of the band -> 'left'; right of
   it -> 'right'.
5. Command: the heading error is the bearing of the intersection,
   ``atan((x - cx) / fx)`` with fx = (W / 2) / tan(hfov / 2) the focal length
   [px]; the correction angle is its negative (REP-103: positive yaw turns
   left, and a vanishing point to the right needs a right turn), capped at
   the paper's 5 deg, and zero inside the dead band.
   ``angular_z = gain_per_s * correction_rad`` [rad/s], ``linear_x =
   forward_speed_mps`` [m/s] (the paper's 1.8 km/h). The original code
   nudged by a fixed 0.01 rad/s; the proportional, capped form keeps the
   paper's 5 deg limit and is 0 on the centre line.

   Dead band and lateral error: the intersection is (nearly) the far end of
   the lane, so steering towards it is a pursuit of a point 10+ m ahead: a
   lateral offset d shows only as a bearing of d / distance (0.15 m at 12 m:
   0.7 deg, 2 px at 320 px), far inside the original's 40 px band (6.8 deg at
   640 px). With that band the robot keeps any offset; the closed-loop
   rostest therefore runs with ``dead_band_px = 0`` (see
   config/row_centring.yaml), where the offset shrinks as the end point
   approaches (0.15 m -> ~0.04 m over 10 m in lane 1).

Bad input never raises: missing, empty, too small or mis-shaped masks return
``status='no_estimate'`` with a reason ('no sky mask', 'no ground mask',
'lines parallel', 'intersection outside image', 'empty frame') and a zero
command; the caller should then ignore the result (not stop the robot).

Pixel convention: pixel-edge coordinates, x right, y down; the pixel in
column j has its centre at x = j + 0.5.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

REASON_NO_SKY = "no sky mask"
REASON_NO_GROUND = "no ground mask"
REASON_PARALLEL = "lines parallel"
REASON_OUTSIDE = "intersection outside image"
REASON_EMPTY = "empty frame"

Point = Tuple[float, float]


@dataclass(frozen=True)
class RowCentringConfig:
    """Parameters of :func:`compute_row_centring`.

    dead_band_px: half width of the 'straight' band around the image centre
        [px] (original: 40 on a 640 px image).
    gain_per_s: angular_z [rad/s] per radian of correction [1/s].
    max_correction_rad: cap on the heading correction [rad] (paper: 5 deg).
    forward_speed_mps: linear_x of every estimate [m/s] (paper: 1.8 km/h).
    horizontal_fov_rad: camera horizontal field of view [rad], gives the
        focal length (original camera plugin: 1.5184 rad = 87 deg).
    min_mask_area_px: a mask with fewer pixels counts as missing [px].
    band_rows: rows used (median) for each end point of a mask line.
    min_row_pixels: a row needs at least this many mask pixels to be used.
    parallel_tolerance: slope difference |a_g - a_s| [px/px] below which the
        lines count as parallel.
    intersection_margin_px: how far outside the image the intersection may
        lie and still count [px].
    coincident_tolerance_px: lines closer than this at the horizon count as
        one line when they are parallel or meet outside the image [px].
    trace_strips: keep only the lane's own ground / sky strip (see the
        module docstring, 'Strip tracing'); False = the paper's per-row mean
        over the whole mask.
    """

    dead_band_px: float = 40.0
    gain_per_s: float = 1.0
    max_correction_rad: float = math.radians(5.0)
    forward_speed_mps: float = 0.5
    horizontal_fov_rad: float = 1.5184
    min_mask_area_px: int = 200
    band_rows: int = 5
    min_row_pixels: int = 1
    parallel_tolerance: float = 1e-3
    intersection_margin_px: float = 0.0
    coincident_tolerance_px: float = 10.0
    trace_strips: bool = True

    def __post_init__(self) -> None:
        def num(name: str) -> float:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"RowCentringConfig.{name} must be a finite number, got {v!r}")
            return float(v)

        if num("dead_band_px") < 0:
            raise ValueError("RowCentringConfig.dead_band_px must be >= 0")
        if num("gain_per_s") < 0:
            raise ValueError("RowCentringConfig.gain_per_s must be >= 0")
        if not 0 < num("max_correction_rad") < math.pi / 2:
            raise ValueError("RowCentringConfig.max_correction_rad must be in (0, pi/2)")
        if num("forward_speed_mps") < 0:
            raise ValueError("RowCentringConfig.forward_speed_mps must be >= 0")
        if not 0 < num("horizontal_fov_rad") < math.pi:
            raise ValueError("RowCentringConfig.horizontal_fov_rad must be in (0, pi)")
        for name, low in (("min_mask_area_px", 0), ("band_rows", 1), ("min_row_pixels", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
                raise ValueError(f"RowCentringConfig.{name} must be an int >= {low}, got {v!r}")
        if num("parallel_tolerance") <= 0:
            raise ValueError("RowCentringConfig.parallel_tolerance must be > 0")
        if num("intersection_margin_px") < 0:
            raise ValueError("RowCentringConfig.intersection_margin_px must be >= 0")
        if num("coincident_tolerance_px") < 0:
            raise ValueError("RowCentringConfig.coincident_tolerance_px must be >= 0")
        if not isinstance(self.trace_strips, (bool, np.bool_)):
            raise ValueError(f"RowCentringConfig.trace_strips must be a bool, got {self.trace_strips!r}")


@dataclass(frozen=True)
class RowCentringResult:
    """Outcome of one frame.

    status: 'ok' or 'no_estimate'; reason: '' when ok, else one of the
    REASON_* strings; intersection_px: (x, y) [px] or None; decision:
    'straight' | 'left' | 'right' ('none' without estimate); offset_px:
    x_int - cx [px] (NaN without estimate); heading_error_rad: atan of the
    offset over the focal length, positive to the right (NaN without
    estimate); correction_rad: capped yaw correction, positive = turn left;
    linear_x [m/s], angular_z [rad/s]: the command (both 0 without estimate);
    ground_points / sky_points: (top, bottom) points [px] of each line when
    found; image_size: (W, H) [px].
    """

    status: str
    reason: str
    intersection_px: Optional[Point]
    decision: str
    offset_px: float
    heading_error_rad: float
    correction_rad: float
    linear_x: float
    angular_z: float
    ground_points: Optional[Tuple[Point, Point]]
    sky_points: Optional[Tuple[Point, Point]]
    image_size: Tuple[int, int]

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def _no_estimate(reason: str, size: Tuple[int, int], ground=None, sky=None,
                 intersection=None) -> RowCentringResult:
    return RowCentringResult("no_estimate", reason, intersection, "none", float("nan"),
                             float("nan"), 0.0, 0.0, 0.0, ground, sky, size)


def mask_line_points(mask: np.ndarray, band_rows: int = 5,
                     min_row_pixels: int = 1) -> Optional[Tuple[Point, Point]]:
    """(top, bottom) points of a mask: medians over its first / last usable rows.

    A usable row has >= min_row_pixels pixels; its mid-x is the mean x of
    those pixels (pixel centres). With fewer than 2 usable rows, or when
    the two points share a y, returns None.
    """
    counts = mask.sum(axis=1)
    rows = np.flatnonzero(counts >= min_row_pixels)
    if rows.size < 2:
        return None
    k = int(min(band_rows, rows.size // 2))
    cols = np.arange(mask.shape[1], dtype=np.float64) + 0.5
    sums = mask.astype(np.float64) @ cols
    mid_x = sums[rows] / counts[rows]
    top = (float(np.median(mid_x[:k])), float(np.median(rows[:k])) + 0.5)
    bottom = (float(np.median(mid_x[-k:])), float(np.median(rows[-k:])) + 0.5)
    if bottom[1] <= top[1]:
        return None
    return top, bottom


def _runs_per_row(m: np.ndarray) -> Tuple[List[int], List[int], List[int]]:
    """The runs of True of every row of a boolean mask at once: (starts, ends, first) as lists, where the
    runs of row r are starts[first[r]:first[r + 1]] to ends[...] (end columns exclusive), left to right."""
    h, w = m.shape
    padded = np.zeros((h, w + 2), dtype=np.int8)
    padded[:, 1:-1] = m
    d = np.diff(padded, axis=1)
    start_rows, starts = np.nonzero(d == 1)
    ends = np.nonzero(d == -1)[1]
    first = np.searchsorted(start_rows, np.arange(h + 1))
    return starts.tolist(), ends.tolist(), first.tolist()


def trace_strip(mask: np.ndarray, from_bottom: bool, start_x: Optional[float] = None) -> np.ndarray:
    """The one connected strip of a mask that runs through the image from one edge.

    Starts in the first non-empty row seen from the bottom (``from_bottom``,
    the ground) or from the top (the sky) with the run of pixels that holds
    ``start_x`` [px, pixel edges; default the image centre] or lies nearest
    to it (the leftmost of equals); then walks row by row, keeping in each row
    the run that overlaps the previous row's run most (the leftmost of
    equals), and stops at the first row without an overlapping run. Returns a
    boolean mask of the kept runs (same shape).
    """
    m = np.asarray(mask, dtype=bool)
    h, w = m.shape
    out = np.zeros((h, w), dtype=bool)
    x0 = w / 2.0 if start_x is None else float(start_x)
    all_starts, all_ends, first = _runs_per_row(m)
    prev = None
    for r in (range(h - 1, -1, -1) if from_bottom else range(h)):
        lo, hi = first[r], first[r + 1]
        if lo == hi:
            if prev is None:
                continue
            break
        if prev is None:
            i = min(range(lo, hi), key=lambda j: max(0.0, all_starts[j] - x0, x0 - all_ends[j]))
        else:
            i = max(range(lo, hi), key=lambda j: min(all_ends[j], prev[1]) - max(all_starts[j], prev[0]))
            if min(all_ends[i], prev[1]) - max(all_starts[i], prev[0]) <= 0:
                break
        out[r, all_starts[i]:all_ends[i]] = True
        prev = (all_starts[i], all_ends[i])
    return out


def line_through(points: Tuple[Point, Point]) -> Tuple[float, float]:
    """(a, b) of the line x = a * y + b through two points with different y."""
    (x1, y1), (x2, y2) = points
    a = (x2 - x1) / (y2 - y1)
    return a, x1 - a * y1


def compute_row_centring(ground_mask, sky_mask,
                         config: RowCentringConfig = RowCentringConfig()) -> RowCentringResult:
    """Steering from the ground and sky masks of one frame (see module docstring).

    ground_mask, sky_mask: (H, W) boolean (or 0/1) arrays of the same size, or
    None when the class was not detected. Never raises on bad masks.
    """
    arrays = []
    for m in (ground_mask, sky_mask):
        if m is None:
            arrays.append(None)
            continue
        try:
            a = np.asarray(m)
        except Exception:  # e.g. ragged nested lists
            return _no_estimate(REASON_EMPTY, (0, 0))
        if a.ndim != 2 or a.size == 0 or a.dtype == object:
            return _no_estimate(REASON_EMPTY, (0, 0))
        if a.dtype != np.bool_:
            with np.errstate(invalid="ignore"):
                a = np.nan_to_num(a.astype(np.float64), nan=0.0) > 0.5
        arrays.append(a)
    ground, sky = arrays
    if ground is None and sky is None:
        return _no_estimate(REASON_EMPTY, (0, 0))
    shape = (ground if ground is not None else sky).shape
    if ground is not None and sky is not None and ground.shape != sky.shape:
        return _no_estimate(REASON_EMPTY, (0, 0))
    h, w = int(shape[0]), int(shape[1])
    size = (w, h)
    if ground is not None and sky is not None and not ground.any() and not sky.any():
        return _no_estimate(REASON_EMPTY, size)

    def points(m):
        if m is None or int(m.sum()) < max(config.min_mask_area_px, 1):
            return None
        return mask_line_points(m, config.band_rows, config.min_row_pixels)

    if config.trace_strips:
        ground = trace_strip(ground, from_bottom=True) if ground is not None else None
        sky = trace_strip(sky, from_bottom=False) if sky is not None else None
    gp = points(ground)
    sp = points(sky)
    if gp is None:
        return _no_estimate(REASON_NO_GROUND, size, None, sp)
    if sp is None:
        return _no_estimate(REASON_NO_SKY, size, gp, None)
    ag, bg = line_through(gp)
    as_, bs = line_through(sp)
    parallel = abs(ag - as_) < config.parallel_tolerance
    if not parallel:
        y = (bs - bg) / (ag - as_)
        x = ag * y + bg
    mgn = config.intersection_margin_px
    inside = (not parallel and math.isfinite(x) and math.isfinite(y)
              and -mgn <= x <= w + mgn and -mgn <= y <= h + mgn)
    if not inside:
        y_h = (sp[1][1] + gp[0][1]) / 2.0          # sky bottom / ground top
        xg, xs = ag * y_h + bg, as_ * y_h + bs
        if abs(xg - xs) <= config.coincident_tolerance_px:
            x, y = (xg + xs) / 2.0, y_h
        elif parallel:
            return _no_estimate(REASON_PARALLEL, size, gp, sp)
        else:
            inter = (float(x), float(y)) if math.isfinite(x) and math.isfinite(y) else None
            return _no_estimate(REASON_OUTSIDE, size, gp, sp, inter)

    cx = w / 2.0
    offset = x - cx
    fx = cx / math.tan(config.horizontal_fov_rad / 2.0)
    heading = math.atan2(offset, fx)
    if -config.dead_band_px < offset <= config.dead_band_px:
        decision, correction = "straight", 0.0
    else:
        decision = "right" if offset > 0 else "left"
        correction = max(-config.max_correction_rad, min(config.max_correction_rad, -heading))
    return RowCentringResult("ok", "", (float(x), float(y)), decision, float(offset), float(heading),
                             float(correction), float(config.forward_speed_mps),
                             float(config.gain_per_s * correction), gp, sp, size)


def _line_ends(points: Tuple[Point, Point], height: int) -> Tuple[Tuple[int, int], Tuple[int, int]]:
    a, b = line_through(points)
    return (int(round(b)), 0), (int(round(a * height + b)), int(height))


def draw_row_centring(image: np.ndarray, result: RowCentringResult,
                      ground_mask: Optional[np.ndarray] = None, sky_mask: Optional[np.ndarray] = None,
                      config: RowCentringConfig = RowCentringConfig(), bgr: bool = False,
                      alpha: float = 0.35) -> np.ndarray:
    """A copy of an (H, W, 3) uint8 image with the masks, lines, points and decision drawn.

    Colours follow the paper's Fig. 10: ground points red, sky points yellow,
    ground line green, sky line blue, intersection magenta; the dead band is
    two grey vertical lines. Colours are RGB unless ``bgr`` is True.
    """
    import cv2

    img = np.array(image, dtype=np.uint8, copy=True)
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    h, w = img.shape[:2]

    def col(rgb):
        return tuple(int(c) for c in (rgb[::-1] if bgr else rgb))

    for m, tint in ((ground_mask, (140, 90, 40)), (sky_mask, (60, 140, 255))):
        if m is not None and np.asarray(m).shape == (h, w):
            sel = np.asarray(m).astype(bool)
            img[sel] = ((1 - alpha) * img[sel] + alpha * np.array(col(tint))).astype(np.uint8)
    cx = w / 2.0
    for xb in (cx - config.dead_band_px, cx + config.dead_band_px):
        cv2.line(img, (int(round(xb)), 0), (int(round(xb)), h), col((160, 160, 160)), 1)
    for pts, lcol, pcol in ((result.ground_points, (0, 200, 0), (255, 0, 0)),
                            (result.sky_points, (0, 0, 255), (255, 230, 0))):
        if pts is None:
            continue
        p0, p1 = _line_ends(pts, h)
        cv2.line(img, p0, p1, col(lcol), 2, cv2.LINE_AA)
        for (px, py) in pts:
            cv2.circle(img, (int(round(px)), int(round(py))), 6, col(pcol), -1, cv2.LINE_AA)
    if result.intersection_px is not None:
        ix, iy = result.intersection_px
        if abs(ix) < 1e5 and abs(iy) < 1e5:
            cv2.circle(img, (int(round(ix)), int(round(iy))), 9, col((255, 0, 255)), 3, cv2.LINE_AA)
    if result.ok:
        text = (f"{result.decision}  x={result.intersection_px[0]:.0f}px  "
                f"corr={math.degrees(result.correction_rad):+.1f}deg  wz={result.angular_z:+.3f}rad/s")
    else:
        text = f"no estimate: {result.reason}"
    cv2.putText(img, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, col((0, 0, 0)), 3, cv2.LINE_AA)
    cv2.putText(img, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, col((255, 255, 255)), 1, cv2.LINE_AA)
    return img
