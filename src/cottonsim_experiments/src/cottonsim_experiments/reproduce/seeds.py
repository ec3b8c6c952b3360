"""Mean and spread of report figures over several runs (seeds), so no single lucky run stands for a result."""
from __future__ import annotations

import math
from typing import Dict, Iterable, Mapping, Sequence

# Report keys summarised by default (see evaluation.experiment for their meaning).
REPORT_KEYS = ("cr_percent", "cr_percent_010m", "ae_m", "rmse_m", "plant_contacts", "cross_track_mean_m",
               "cross_track_max_m", "sim_duration_s", "wall_duration_s", "real_time_factor",
               "localization_error_mean_m", "localization_error_max_m")


def spread(values: Iterable[float]) -> Dict[str, float]:
    """n, mean, sample standard deviation (0 for one value), min and max of the finite values.

    Non-finite values are left out and counted in ``n_dropped``; with no
    finite value every statistic is NaN.
    """
    vals = [float(v) for v in values]
    finite = [v for v in vals if math.isfinite(v)]
    n = len(finite)
    if n == 0:
        nan = float("nan")
        return {"n": 0, "n_dropped": len(vals), "mean": nan, "std": nan, "min": nan, "max": nan}
    mean = sum(finite) / n
    std = math.sqrt(sum((v - mean) ** 2 for v in finite) / (n - 1)) if n > 1 else 0.0
    return {"n": n, "n_dropped": len(vals) - n, "mean": mean, "std": std, "min": min(finite), "max": max(finite)}


def aggregate_reports(reports: Sequence[Mapping[str, object]], keys: Sequence[str] = REPORT_KEYS
                      ) -> Dict[str, Dict[str, float]]:
    """Per key, the spread of that figure over ``reports`` (keys no report holds are left out).

    A report missing a key another report has contributes NaN (counted as
    dropped), so a figure never silently averages over fewer runs than it
    seems to.
    """
    out = {}
    for key in keys:
        present = [r.get(key) for r in reports]
        if all(v is None for v in present):
            continue
        out[key] = spread(float("nan") if v is None else float(v) for v in present)
    return out


def format_spread(stats: Mapping[str, float], scale: float = 1.0, digits: int = 3) -> str:
    """'mean +/- std (min..max, n=N)' with values multiplied by ``scale``."""
    if not stats or stats.get("n", 0) == 0:
        return "-"
    m, s = stats["mean"] * scale, stats["std"] * scale
    lo, hi = stats["min"] * scale, stats["max"] * scale
    if stats["n"] == 1:
        return f"{m:.{digits}f} (n=1)"
    return f"{m:.{digits}f} ± {s:.{digits}f} ({lo:.{digits}f}..{hi:.{digits}f}, n={stats['n']})"
