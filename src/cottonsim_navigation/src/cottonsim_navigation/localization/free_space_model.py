"""Free-space check of laser beams: a beam that crosses mapped obstacles before its end point is unlikely.

Why: the likelihood field only looks at where a beam ends. In the farm the
hedges of touching 0.7 m plants are continuous, so a pose one plant pitch
(0.7 m) further along a row puts the end points of the beams that see the row
ends into the hedge instead of onto the first plant: the likelihood field
scores both poses the same, and a re-spread filter (after a kidnap) may settle
on the wrong one. What tells them apart is the way *to* the end point: from
the wrong pose the beam would have had to pass through the first plant.

The crop is not a wall, though: at the scan's height (0.13-0.38 m above the
ground) the lidar sees between the stems, and on the farm generator's
ground-truth map (solid 0.7 m discs) ~40-50 % of the beams of the true pose
cross some mapped plant before they end. A hard "blocked beam" test (ROS
amcl's beam model, short readings) would punish the truth as well. So the
check is a transmission model (Beer-Lambert): a beam that crosses ``L`` metres
of mapped obstacle on its checked stretch survives with probability
``exp(-L / decay_length_m)``, and that factor multiplies *this beam's*
likelihood ``pz`` before the laser model combines the beams:

* ``likelihood_field_prob`` (product of the beams): the particle's weight is
  ``prod(pz_j * f_j)``, i.e. the field's weight times ``exp(-sum L_j / decay)``;
* ``likelihood_field`` (ROS amcl's ``1 + sum(pz^3)``): ``1 + sum((pz_j * f_j)^3)``.
  A crossing beam counts like a beam that missed, no more. Multiplying this
  flat sum (it varies by a factor of ~10 at most) by the product of the
  factors of all beams instead would let the free-space check outweigh the
  scan: at the truth ~40-50 % of the beams cross some mapped plant, so the
  set drifted to poses whose beams cross nothing (off the rows, replayed
  drives 10-16 m from the truth: benchmarks/amcl_replay.py).

The last ``check_length_m`` (1 m) before ``range - tolerance_m`` is checked
at points ``sample_spacing_m`` (0.1 m) apart: that is where the pose one pitch
off crosses the first plant. The rest of the beam back to the sensor is
checked coarsely (``far_sample_spacing_m``, 0.5 m): a pose metres off (a
kidnap towards the rows) would see through whole rows. A beam counts at most
``max_crossed_m`` (1 m), so where the lidar sees between the stems at the
truth too, one beam cannot veto a pose.

:class:`FreeSpaceCheckedField` wraps a :class:`~.sensor_models.LikelihoodField`
(same interface) and multiplies its weights by this factor while
:attr:`FreeSpaceCheckedField.enabled` is true.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from cottonsim_common.validation import require_fields, require_instance
from .sensor_models import LikelihoodField, Scan


@dataclass(frozen=True)
class FreeSpaceConfig:
    """Transmission model of the free-space check (not in ROS amcl).

    tolerance_m [m]: the last part of each beam that is not checked (its end point sits on or in the
        obstacle it hit; map and range noise); default 0.2;
    check_length_m [m]: the stretch before that which is checked (one plant pitch and more; the far part
        of a beam, where the lidar sees between the stems, is not); default 1.0, i.e. at most this much
        crossed obstacle counts per beam (one bad beam cannot veto a pose);
    sample_spacing_m [m]: distance between the checked points on that stretch; default 0.1;
    far_sample_spacing_m [m]: spacing of the checked points on the rest of the beam, back to the sensor
        (coarse: sees a pose metres off whose beams would cross whole rows); 0 = not checked; default 0.5 (0.35: ~1.4x the CPU time);
    max_crossed_m [m]: crossed length counted per beam at most (one bad beam cannot veto a pose); default 1.0;
    decay_length_m [m]: crossed obstacle length that lowers a beam's likelihood by a factor e; default 1.0.
    """

    tolerance_m: float = 0.2
    check_length_m: float = 1.0
    sample_spacing_m: float = 0.1
    far_sample_spacing_m: float = 0.5
    max_crossed_m: float = 1.0
    decay_length_m: float = 1.0

    @property
    def n_samples(self) -> int:
        """Checked points per beam."""
        return max(1, int(round(self.check_length_m / self.sample_spacing_m)))

    def __post_init__(self) -> None:
        require_fields(self, non_negative=("tolerance_m", "far_sample_spacing_m"),
                       positive=("check_length_m", "sample_spacing_m", "max_crossed_m", "decay_length_m"))


@njit(cache=True, nogil=True)
def _beam_crossed(x0, y0, dc, ds, r, occupied, ox, oy, inv, tolerance, spacing, n_samples, far_spacing,
                  max_crossed):
    """Crossed obstacle length [m] of one beam from (x0, y0) along (dc, ds) ending at range r (sampled:
    n_samples points ``spacing`` apart before r - tolerance, then every ``far_spacing`` back to the sensor),
    capped at max_crossed."""
    h, w = occupied.shape
    t = r - tolerance - 0.5 * spacing
    # the sample point in cell units, stepped back towards the sensor incrementally
    gx = (x0 + t * dc - ox) * inv
    gy = (y0 + t * ds - oy) * inv
    crossed = 0.0
    k = 0
    step = spacing
    sx = spacing * dc * inv
    sy = spacing * ds * inv
    while t > 0.0 and crossed < max_crossed:
        if k == n_samples:
            if far_spacing <= 0.0:
                break
            step = far_spacing
            sx = far_spacing * dc * inv
            sy = far_spacing * ds * inv
        if gx >= 0.0 and gy >= 0.0:          # int() truncates: the floor for these
            mx = int(gx)
            my = int(gy)
            if mx < w and my < h and occupied[my, mx]:
                crossed += step
        t -= step
        gx -= sx
        gy -= sy
        k += 1
    return min(crossed, max_crossed)


@njit(cache=True, nogil=True)
def _crossed_log_factors(particles, lx, ly, beam_c, beam_s, beam_r, occupied, ox, oy, res, tolerance, spacing,
                         n_samples, far_spacing, max_crossed, decay, per_beam):
    """Per particle: -sum_j L_j / decay, L_j = crossed length of beam j (sampled, capped at max_crossed);
    with ``per_beam`` (one particle) the L_j of each beam instead."""
    n = particles.shape[0]
    inv = 1.0 / res
    out = np.empty(beam_c.shape[0] if per_beam else n)
    for i in range(n):
        c = math.cos(particles[i, 2])
        s = math.sin(particles[i, 2])
        x0 = particles[i, 0] + c * lx - s * ly
        y0 = particles[i, 1] + s * lx + c * ly
        total = 0.0
        for j in range(beam_c.shape[0]):
            crossed = _beam_crossed(x0, y0, c * beam_c[j] - s * beam_s[j], s * beam_c[j] + c * beam_s[j],
                                    beam_r[j], occupied, ox, oy, inv, tolerance, spacing, n_samples,
                                    far_spacing, max_crossed)
            if per_beam:
                out[j] = crossed
            total += crossed
        if not per_beam:
            out[i] = -total / decay
    return out


@njit(cache=True, nogil=True)
def _per_beam_sum_weights(particles, bx, by, lx, ly, beam_c, beam_s, beam_r, pz_map, pz_outside, occupied, ox, oy,
                          res, tolerance, spacing, n_samples, far_spacing, max_crossed, decay):
    """Per particle: 1 + sum_j (pz_j * exp(-L_j / decay))^3 (ROS amcl's likelihood_field with each beam's
    likelihood times its own free-space factor); beams with beam_r <= 0 are not checked (factor 1)."""
    n = particles.shape[0]
    h, w = pz_map.shape
    inv = 1.0 / res
    out = np.empty(n)
    for i in range(n):
        c = math.cos(particles[i, 2])
        s = math.sin(particles[i, 2])
        x = particles[i, 0]
        y = particles[i, 1]
        x0 = x + c * lx - s * ly
        y0 = y + s * lx + c * ly
        total = 1.0
        for j in range(bx.shape[0]):
            mx = int(math.floor((x + c * bx[j] - s * by[j] - ox) * inv))
            my = int(math.floor((y + s * bx[j] + c * by[j] - oy) * inv))
            pz = pz_map[my, mx] if (0 <= mx < w and 0 <= my < h) else pz_outside
            if beam_r[j] > 0.0:
                crossed = _beam_crossed(x0, y0, c * beam_c[j] - s * beam_s[j], s * beam_c[j] + c * beam_s[j],
                                        beam_r[j], occupied, ox, oy, inv, tolerance, spacing, n_samples,
                                        far_spacing, max_crossed)
                pz *= math.exp(-crossed / decay)
            total += pz * pz * pz
        out[i] = total
    return out


class FreeSpaceCheckedField:
    """A likelihood field whose weights also pay for obstacle crossed on the way (see the module doc).

    Everything but :meth:`weights` is the wrapped field's (``spec``, ``distance_m``, ``select_beams``,
    ``config``, ...). ``enabled`` (default true) switches the check on and off at run time.
    """

    CHUNK = 256                 # particles checked per round (see weights)
    negligible_ratio = 1e-9     # a weight below this times the best one is negligible

    def __init__(self, field: LikelihoodField, config: FreeSpaceConfig = FreeSpaceConfig()) -> None:
        require_instance("field", field, LikelihoodField)
        require_instance("config", config, FreeSpaceConfig)
        self.field = field
        self.free_space_config = config
        self.enabled = True
        self._occupied = np.ascontiguousarray(field.distance_m <= 0.0)      # the field's obstacle cells

    def __getattr__(self, name):
        # only called for attributes this wrapper does not have: the wrapped field's
        if name == "field":
            raise AttributeError(name)
        return getattr(self.field, name)

    def _beams(self, particles, scan: Scan):
        """(particles as a contiguous (N, 3) array, the used beams' end points (K, 2) in base_link, the
        laser's x, y in base_link, the beams' vectors vx, vy from the laser and their lengths r)."""
        parts = np.ascontiguousarray(particles, dtype=float)
        if parts.ndim != 2 or parts.shape[1] != 3:
            raise ValueError(f"particles must be an (N, 3) array, got shape {parts.shape}")
        pts = self.field.select_beams(scan)
        lx, ly, _ = scan.laser_pose
        vx, vy = pts[:, 0] - lx, pts[:, 1] - ly
        return parts, pts, float(lx), float(ly), vx, vy, np.hypot(vx, vy)

    def crossed_log_factors(self, particles: np.ndarray, scan: Scan) -> np.ndarray:
        """ln of the free-space factor (N,) of each particle (<= 0) for the beams the field uses."""
        parts, _, lx, ly, vx, vy, r = self._beams(particles, scan)
        keep = r > 1e-9
        r, vx, vy = r[keep], vx[keep], vy[keep]
        c = self.free_space_config
        spec = self.field.spec
        return _crossed_log_factors(parts, lx, ly, np.ascontiguousarray(vx / r),
                                    np.ascontiguousarray(vy / r), np.ascontiguousarray(r), self._occupied,
                                    spec.origin_x_m, spec.origin_y_m, spec.resolution_m, c.tolerance_m,
                                    c.sample_spacing_m, c.n_samples, c.far_sample_spacing_m, c.max_crossed_m,
                                    c.decay_length_m, False)

    def crossed_lengths(self, pose, scan: Scan) -> np.ndarray:
        """Crossed obstacle length [m] (capped at max_crossed_m) of each beam the field uses, robot at
        ``pose`` (x_m, y_m, yaw_rad); same order as ``select_beams`` (0 for a zero-length beam)."""
        p, pts, lx, ly, vx, vy, r = self._beams(np.asarray(pose, dtype=float).reshape(1, 3), scan)
        keep = r > 1e-9
        c = self.free_space_config
        spec = self.field.spec
        out = np.zeros(pts.shape[0])
        if np.any(keep):
            out[keep] = _crossed_log_factors(p, float(lx), float(ly), np.ascontiguousarray(vx[keep] / r[keep]),
                                             np.ascontiguousarray(vy[keep] / r[keep]),
                                             np.ascontiguousarray(r[keep]), self._occupied, spec.origin_x_m,
                                             spec.origin_y_m, spec.resolution_m, c.tolerance_m,
                                             c.sample_spacing_m, c.n_samples, c.far_sample_spacing_m,
                                             c.max_crossed_m, 1.0, True)
        return out

    def weights(self, particles: np.ndarray, scan: Scan) -> np.ndarray:
        """The wrapped field's weights with each beam's free-space factor while ``enabled`` (module doc):
        for likelihood_field_prob the field's weights times exp(crossed_log_factors), for likelihood_field
        1 + sum((pz * factor)^3) over the beams.

        likelihood_field_prob: the factor is <= 1, so a particle whose field weight is below ``negligible_ratio`` times the best
        checked particle's final weight stays negligible whatever its factor: the particles are checked in
        order of their field weight, in chunks, until the rest are that small; the rest keep their field
        weight times the smallest factor found (they are negligible either way). This saves most of the
        check's cost right after a re-spread, when the likelihood field already rules out most particles.
        """
        if self.enabled and self.field.config.model == "likelihood_field":
            return self._per_beam_sum_weights(particles, scan)
        w = self.field.weights(particles, scan)
        if not self.enabled:
            return w
        parts = np.asarray(particles, dtype=float)
        order = np.argsort(-w, kind="stable")
        out = w.copy()
        best = 0.0
        lowest = 1.0
        chunk = self.CHUNK
        start = 0
        while start < order.size:
            if start > 0 and w[order[start]] < best * self.negligible_ratio:
                break
            idx = order[start:start + chunk]
            # (>= e^-(beams * max_crossed_m / decay_length_m): no underflow for any sane setting)
            f = np.exp(self.crossed_log_factors(parts[idx], scan))
            out[idx] = w[idx] * f
            best = max(best, float(out[idx].max()))
            lowest = min(lowest, float(f.min()))
            start += chunk
        if start < order.size:
            rest = order[start:]
            out[rest] = w[rest] * lowest
        return out

    def _per_beam_sum_weights(self, particles: np.ndarray, scan: Scan) -> np.ndarray:
        parts, pts, lx, ly, vx, vy, r = self._beams(particles, scan)
        safe = np.where(r > 1e-9, r, 1.0)
        c = self.free_space_config
        spec = self.field.spec
        return _per_beam_sum_weights(parts, np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1]),
                                     lx, ly, np.ascontiguousarray(vx / safe),
                                     np.ascontiguousarray(vy / safe), np.where(r > 1e-9, r, 0.0),
                                     self.field.pz_map, self.field.pz_outside, self._occupied, spec.origin_x_m,
                                     spec.origin_y_m, spec.resolution_m, c.tolerance_m, c.sample_spacing_m,
                                     c.n_samples, c.far_sample_spacing_m, c.max_crossed_m, c.decay_length_m)
