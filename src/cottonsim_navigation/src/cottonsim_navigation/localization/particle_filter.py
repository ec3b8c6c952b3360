"""A KLD-sampling particle filter over planar poses (the machinery of ROS amcl's pf library).

Why: AMCL's belief about the robot pose is a weighted set of pose samples.
This module holds that set and everything done to it that does not depend on
sensors: drawing initial sets (a Gaussian around a given pose, or uniform over
the map's free cells for global localisation), normalising weights after a
measurement, resampling, choosing how many particles are needed, injecting
random particles when the measurements stop fitting, and clustering the set
to report a pose estimate with a covariance.

Algorithms (as in ROS amcl / Probabilistic Robotics ch. 4 and 8):

* Resampling is systematic (low-variance): one random offset, N evenly
  spaced pointers into the cumulative weights.
* KLD-sampling (Fox 2003): the number of particles is the smallest n with
  ``n >= (k - 1) / (2 kld_err) * (1 - 2/(9(k-1)) + sqrt(2/(9(k-1))) * kld_z)^3``,
  where k is the number of occupied histogram bins (0.5 m x 0.5 m x 10 deg),
  clamped to [min_particles, max_particles]. Like ROS amcl, ``kld_z`` is used
  directly as the normal quantile in the formula (amcl's default 0.99).
  Vectorised: max_particles systematic samples are drawn, shuffled, and the
  set is cut at the first prefix whose size reaches the bound for its own
  bin count (equivalent to amcl's draw-until-enough loop).
* Augmented MCL recovery: short- and long-term averages of the measurement
  likelihood (alpha_fast, alpha_slow); while the short-term one falls below
  the long-term one, a fraction ``max(0, 1 - w_fast / w_slow)`` of the new
  set is drawn uniformly from free space. alpha = 0 (amcl's default) disables it.
* Clusters: occupied bins that touch (26-neighbourhood, yaw wraps) form a
  cluster; the estimate is the weighted mean of the heaviest cluster, the
  covariance is its weighted x-y covariance plus amcl's circular yaw variance
  ``-2 ln R`` (R = length of the mean heading vector).

Particles are (N, 3) arrays of (x_m, y_m, yaw_rad); weights (N,) sum to 1.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from cottonsim_common.angles import wrap_angle
from cottonsim_common.validation import require_fields, require_instance
from ..core.grid import GridSpec


@dataclass(frozen=True)
class ParticleFilterConfig:
    """Particle-set parameters (ROS amcl names in brackets; defaults = the original's values).

    min_particles, max_particles: bounds of the adaptive set size [min_particles, max_particles];
    kld_err: max error between true and estimated distribution [kld_err];
    kld_z: normal quantile used in the KLD bound [kld_z] (used as given, like amcl);
    bin_size_xy_m, bin_size_yaw_rad: KLD histogram / clustering bin size (amcl: 0.5 m, 10 deg);
    alpha_slow, alpha_fast: recovery averaging rates [recovery_alpha_slow/fast] (0 = off).
    """

    min_particles: int = 500
    max_particles: int = 2000
    kld_err: float = 0.05
    kld_z: float = 0.99
    bin_size_xy_m: float = 0.5
    bin_size_yaw_rad: float = math.radians(10.0)
    alpha_slow: float = 0.0
    alpha_fast: float = 0.0

    def __post_init__(self) -> None:
        require_fields(self, counts=("min_particles", "max_particles"),
                       positive=("kld_z", "bin_size_xy_m", "bin_size_yaw_rad"))
        if self.min_particles > self.max_particles:
            raise ValueError(f"min_particles ({self.min_particles}) must not exceed max_particles "
                             f"({self.max_particles})")
        if not (0 < self.kld_err < 1):
            raise ValueError(f"kld_err must lie in (0, 1), got {self.kld_err!r}")
        if not (0 <= self.alpha_slow <= 1 and 0 <= self.alpha_fast <= 1):
            raise ValueError(f"alpha_slow and alpha_fast must lie in [0, 1], got {self.alpha_slow}, "
                             f"{self.alpha_fast}")
        if self.alpha_slow > 0 and self.alpha_fast <= self.alpha_slow:
            raise ValueError(f"alpha_fast ({self.alpha_fast}) must exceed alpha_slow ({self.alpha_slow}) "
                             "for recovery to work")


def kld_sample_limit(k, kld_err: float, kld_z: float, min_particles: int, max_particles: int):
    """Particles needed for ``k`` occupied bins (KLD bound, amcl's pf_resample_limit); vectorised.

    k <= 1 -> max_particles (amcl's rule: one bin says nothing about the spread).
    """
    k_arr = np.asarray(k, dtype=float)
    km1 = np.maximum(k_arr - 1.0, 1.0)
    b = 2.0 / (9.0 * km1)
    n = np.ceil(km1 / (2.0 * kld_err) * (1.0 - b + np.sqrt(b) * kld_z) ** 3)
    n = np.clip(n, min_particles, max_particles)
    n = np.where(k_arr <= 1, max_particles, n).astype(np.int64)
    return int(n) if np.ndim(k) == 0 else n


def normalise_weights(weights) -> np.ndarray:
    """Weights / their sum; ValueError when any is negative or non-finite or all are 0."""
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"weights must be a non-empty 1-D array, got shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError("weights must be finite and >= 0")
    total = w.sum()
    if total <= 0:
        raise ValueError("weights sum to 0")
    return w / total


def systematic_resample_indices(weights, n: int, rng: Optional[np.random.Generator] = None) -> np.ndarray:
    """Low-variance resampling: indices (n,) drawn with probability ~ weights.

    One uniform offset u in [0, 1/n); pointers u + i/n into the cumulative
    weights. Each particle is copied floor(n w) or ceil(n w) times.
    """
    w = normalise_weights(weights)
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    rng = rng if rng is not None else np.random.default_rng()
    cdf = np.cumsum(w)
    cdf[-1] = 1.0
    pointers = (rng.random() + np.arange(int(n))) / n
    return np.minimum(np.searchsorted(cdf, pointers, side="right"), w.size - 1)


def effective_sample_size(weights) -> float:
    """N_eff = 1 / sum(w^2) of the normalised weights."""
    w = normalise_weights(weights)
    return float(1.0 / np.sum(w * w))


def weight_entropy(weights) -> float:
    """Shannon entropy -sum(w ln w) [nats] of the normalised weights (0 = one particle holds all)."""
    w = normalise_weights(weights)
    nz = w[w > 0]
    return float(-np.sum(nz * np.log(nz)))


class _BinIndex:
    """Integer histogram bins of poses and a scalar key per bin (yaw bins wrap around)."""

    OFFSET = 1 << 20

    def __init__(self, bin_xy_m: float, bin_yaw_rad: float) -> None:
        self.bin_xy = bin_xy_m
        self.bin_yaw = bin_yaw_rad
        self.n_yaw = max(1, int(math.ceil(2.0 * math.pi / bin_yaw_rad)))

    def bins(self, particles: np.ndarray) -> np.ndarray:
        b = np.empty((particles.shape[0], 3), dtype=np.int64)
        b[:, 0] = np.floor(particles[:, 0] / self.bin_xy)
        b[:, 1] = np.floor(particles[:, 1] / self.bin_xy)
        b[:, 2] = np.floor((wrap_angle(particles[:, 2]) + math.pi) / self.bin_yaw)
        b[:, 2] %= self.n_yaw
        return b

    def keys(self, b: np.ndarray) -> np.ndarray:
        span = 2 * self.OFFSET
        return ((b[:, 0] + self.OFFSET) * span + (b[:, 1] + self.OFFSET)) * self.n_yaw + (b[:, 2] % self.n_yaw)


@dataclass(frozen=True)
class Cluster:
    """A group of touching particle bins: total weight, weighted mean pose, 3x3 covariance, size."""

    weight: float
    mean: np.ndarray          # (x_m, y_m, yaw_rad)
    covariance: np.ndarray    # 3x3: xy block [m^2], yaw variance [rad^2] (cross terms 0, like amcl)
    count: int


class FreeSpaceSampler:
    """Uniform random poses over the free cells of an occupancy map (global localisation, recovery).

    Free = occupancy value in [0, free_max] (default 19: map_server's free_thresh 0.196).
    Positions are uniform inside the chosen cell, headings uniform in [-pi, pi).
    """

    def __init__(self, occupancy, spec: GridSpec, free_max: int = 19) -> None:
        occ = np.asarray(occupancy)
        if occ.shape != spec.shape:
            raise ValueError(f"occupancy has shape {occ.shape}, the grid spec needs {spec.shape}")
        my, mx = np.nonzero((occ >= 0) & (occ <= free_max))
        if mx.size == 0:
            raise ValueError("the map has no free cells to place particles in")
        self.spec = spec
        self.mx = mx
        self.my = my

    @property
    def n_free(self) -> int:
        return int(self.mx.size)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        pick = rng.integers(0, self.mx.size, size=int(n))
        res = self.spec.resolution_m
        out = np.empty((int(n), 3))
        out[:, 0] = self.spec.origin_x_m + (self.mx[pick] + rng.random(int(n))) * res
        out[:, 1] = self.spec.origin_y_m + (self.my[pick] + rng.random(int(n))) * res
        out[:, 2] = rng.uniform(-math.pi, math.pi, int(n))
        return out


class ParticleFilter:
    """A weighted particle set with KLD-adaptive resampling and recovery (amcl's pf_t)."""

    def __init__(self, config: ParticleFilterConfig = ParticleFilterConfig(),
                 rng: Optional[np.random.Generator] = None) -> None:
        require_instance("config", config, ParticleFilterConfig)
        self.config = config
        self.rng = rng if rng is not None else np.random.default_rng()
        self._bins = _BinIndex(config.bin_size_xy_m, config.bin_size_yaw_rad)
        self.particles = np.zeros((0, 3))
        self.weights = np.zeros(0)
        self.w_slow = 0.0
        self.w_fast = 0.0

    # --- initial sets ------------------------------------------------------------
    def init_gaussian(self, mean, covariance, n: Optional[int] = None) -> None:
        """``n`` (default max_particles) samples of N(mean, covariance); mean (3,), covariance (3, 3)."""
        mu = np.asarray(mean, dtype=float).reshape(-1)
        cov = np.asarray(covariance, dtype=float)
        if mu.shape != (3,) or not np.all(np.isfinite(mu)):
            raise ValueError(f"mean must be 3 finite values (x_m, y_m, yaw_rad), got {mean!r}")
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise ValueError(f"covariance must be a finite 3x3 matrix, got shape {cov.shape}")
        cov = 0.5 * (cov + cov.T)
        evals, evecs = np.linalg.eigh(cov)
        if evals.min() < -1e-9 * max(1.0, abs(evals.max())):
            raise ValueError("covariance must be positive semi-definite")
        n = self.config.max_particles if n is None else int(n)
        z = self.rng.standard_normal((n, 3)) * np.sqrt(np.clip(evals, 0, None))
        parts = mu + z @ evecs.T
        parts[:, 2] = wrap_angle(parts[:, 2])
        self.set_particles(parts)

    def init_uniform(self, sampler: FreeSpaceSampler, n: Optional[int] = None) -> None:
        """``n`` (default max_particles) poses uniform over the sampler's free space."""
        n = self.config.max_particles if n is None else int(n)
        self.set_particles(sampler.sample(n, self.rng))

    def set_particles(self, particles, weights=None) -> None:
        parts = np.array(particles, dtype=float)
        if parts.ndim != 2 or parts.shape[1] != 3 or parts.shape[0] == 0:
            raise ValueError(f"particles must be a non-empty (N, 3) array, got shape {parts.shape}")
        if not np.all(np.isfinite(parts)):
            raise ValueError("particles must be finite")
        self.particles = parts
        self.weights = (np.full(parts.shape[0], 1.0 / parts.shape[0]) if weights is None
                        else normalise_weights(weights))
        if self.weights.shape[0] != parts.shape[0]:
            raise ValueError("weights and particles differ in length")

    @property
    def n(self) -> int:
        return int(self.particles.shape[0])

    def roughen(self, std_xy_m: float, std_yaw_rad: float) -> None:
        """Add N(0, std) noise to every particle (x, y and yaw; weights kept).

        Repeated filter updates on scans of a standing robot have no motion noise to keep the set
        diverse: resampling would collapse it onto a few copies. A little jitter keeps it exploring.
        """
        for name, v in (("std_xy_m", std_xy_m), ("std_yaw_rad", std_yaw_rad)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        if self.n == 0:
            return
        noise = self.rng.standard_normal((self.n, 3)) * np.array([std_xy_m, std_xy_m, std_yaw_rad])
        parts = self.particles + noise
        parts[:, 2] = wrap_angle(parts[:, 2])
        self.particles = parts

    def redraw_fraction(self, mean, covariance, fraction: float) -> int:
        """Replace ``fraction`` (0..1) of the particles, chosen at random, by samples of N(mean, covariance)
        and make the weights uniform; returns how many were replaced. A re-spread after a kidnap can so mix
        two shapes (e.g. narrow across the rows and round)."""
        if isinstance(fraction, bool) or not isinstance(fraction, (int, float)) or not 0.0 <= fraction <= 1.0:
            raise ValueError(f"fraction must lie in [0, 1], got {fraction!r}")
        k = int(round(fraction * self.n))
        if k == 0:
            return 0
        keep = self.particles.copy()
        self.init_gaussian(mean, covariance, n=k)            # validates mean and covariance
        idx = self.rng.choice(keep.shape[0], size=k, replace=False)
        keep[idx] = self.particles
        self.set_particles(keep)
        return k

    # --- measurement ---------------------------------------------------------------
    def update_weights(self, likelihood) -> float:
        """Multiply the weights by per-particle likelihoods (N,), renormalise; returns w_avg.

        Also advances the recovery averages (w_slow, w_fast) as amcl's pf_update_sensor.
        When every likelihood is 0 the weights are reset to uniform.
        """
        lik = np.asarray(likelihood, dtype=float)
        if lik.shape != (self.n,):
            raise ValueError(f"likelihood must have shape ({self.n},), got {lik.shape}")
        if not np.all(np.isfinite(lik)) or np.any(lik < 0):
            raise ValueError("likelihood values must be finite and >= 0")
        w = self.weights * lik
        total = float(w.sum())
        if total <= 0:
            self.weights = np.full(self.n, 1.0 / self.n)
            return 0.0
        self.weights = w / total
        # amcl's w_avg: total / N, with total = sum(w_old * lik) and sum(w_old) = 1.
        w_avg = total / self.n
        cfg = self.config
        self.w_slow = w_avg if self.w_slow == 0.0 else self.w_slow + cfg.alpha_slow * (w_avg - self.w_slow)
        self.w_fast = w_avg if self.w_fast == 0.0 else self.w_fast + cfg.alpha_fast * (w_avg - self.w_fast)
        return w_avg

    # --- resampling ---------------------------------------------------------------------
    def random_fraction(self) -> float:
        """Share of the next set drawn at random (augmented MCL); 0 when recovery is off."""
        if self.config.alpha_slow <= 0 or self.w_slow <= 0:
            return 0.0
        return max(0.0, 1.0 - self.w_fast / self.w_slow)

    def resample(self, sampler: Optional[FreeSpaceSampler] = None) -> int:
        """Draw a new set (KLD-adaptive size, optional random injection); returns its size."""
        cfg = self.config
        m = cfg.max_particles
        idx = systematic_resample_indices(self.weights, m, self.rng)
        new = self.particles[self.rng.permutation(idx)]
        w_diff = self.random_fraction() if sampler is not None else 0.0
        if w_diff > 0:
            inject = self.rng.random(m) < w_diff
            if inject.any():
                new[inject] = sampler.sample(int(inject.sum()), self.rng)
            self.w_slow = self.w_fast = 0.0   # amcl resets the averages after injecting
        n = self._kld_cut(new)
        self.set_particles(new[:n])
        return n

    def _kld_cut(self, ordered: np.ndarray) -> int:
        """Smallest prefix length n with n >= limit(bins occupied by the first n samples)."""
        cfg = self.config
        keys = self._bins.keys(self._bins.bins(ordered))
        _, first = np.unique(keys, return_index=True)
        new_bin = np.zeros(keys.size, dtype=np.int64)
        new_bin[first] = 1
        k = np.cumsum(new_bin)
        limit = kld_sample_limit(k, cfg.kld_err, cfg.kld_z, cfg.min_particles, cfg.max_particles)
        count = np.arange(1, keys.size + 1)
        enough = np.nonzero(count >= limit)[0]
        return int(enough[0] + 1) if enough.size else int(keys.size)

    def occupied_bins(self) -> int:
        """Number of distinct KLD bins the current set occupies."""
        return int(np.unique(self._bins.keys(self._bins.bins(self.particles))).size)

    # --- estimate -------------------------------------------------------------------------
    def clusters(self) -> List[Cluster]:
        """Clusters of touching bins, heaviest first."""
        if self.n == 0:
            return []
        b = self._bins.bins(self.particles)
        keys = self._bins.keys(b)
        ukeys, inverse = np.unique(keys, return_inverse=True)
        ubins = b[np.unique(keys, return_index=True)[1]]
        rows, cols = [], []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dt in (-1, 0, 1):
                    if dx == 0 and dy == 0 and dt == 0:
                        continue
                    nb = ubins + np.array([dx, dy, dt])
                    nkeys = self._bins.keys(nb)
                    pos = np.searchsorted(ukeys, nkeys)
                    pos = np.minimum(pos, ukeys.size - 1)
                    hit = ukeys[pos] == nkeys
                    rows.append(np.nonzero(hit)[0])
                    cols.append(pos[hit])
        r = np.concatenate(rows)
        c = np.concatenate(cols)
        graph = coo_matrix((np.ones(r.size), (r, c)), shape=(ukeys.size, ukeys.size))
        n_comp, comp_of_bin = connected_components(graph, directed=False)
        label = comp_of_bin[inverse]
        out = []
        for lab in range(n_comp):
            sel = label == lab
            out.append(_cluster_stats(self.particles[sel], self.weights[sel]))
        out.sort(key=lambda cl: -cl.weight)
        return out

    def estimate(self) -> Cluster:
        """The heaviest cluster (mean = the pose estimate, covariance as amcl reports it)."""
        cl = self.clusters()
        if not cl:
            raise ValueError("the particle set is empty: initialise the filter first")
        return cl[0]

    def weighted_mean(self) -> Cluster:
        """Statistics of the whole set as one cluster."""
        return _cluster_stats(self.particles, self.weights)


def circular_mean(yaws_rad: np.ndarray, weights: np.ndarray):
    """(mean yaw [rad], mean resultant length R) of yaws with normalised weights.

    R = |sum_i w_i exp(j yaw_i)| is clamped to [0, 1]: the circular variance is -2 ln R, and rounding
    can put R a hair above 1 when the weight sits on equal yaws (one particle, or a collapsed set),
    which would make that variance negative and its square root a math error."""
    c = float(np.dot(weights, np.cos(yaws_rad)))
    s = float(np.dot(weights, np.sin(yaws_rad)))
    return math.atan2(s, c), min(math.hypot(c, s), 1.0)


def mean_resultant_length(yaws_rad: np.ndarray, weights: np.ndarray) -> float:
    """R of :func:`circular_mean` (clamped to [0, 1])."""
    return circular_mean(yaws_rad, weights)[1]


def _cluster_stats(particles: np.ndarray, weights: np.ndarray) -> Cluster:
    total = float(weights.sum())
    w = weights / total if total > 0 else np.full(weights.size, 1.0 / weights.size)
    mx = float(np.dot(w, particles[:, 0]))
    my = float(np.dot(w, particles[:, 1]))
    yaw, r = circular_mean(particles[:, 2], w)
    dx = particles[:, 0] - mx
    dy = particles[:, 1] - my
    cov = np.zeros((3, 3))
    cov[0, 0] = float(np.dot(w, dx * dx))
    cov[1, 1] = float(np.dot(w, dy * dy))
    cov[0, 1] = cov[1, 0] = float(np.dot(w, dx * dy))
    cov[2, 2] = -2.0 * math.log(r) if r > 1e-12 else 2.0 * math.pi ** 2 / 3.0
    return Cluster(total, np.array([mx, my, yaw]), cov, int(particles.shape[0]))
