"""Fewer points to draw, the same picture: a curve thinned for display, keeping its extremes.

A trace of 3000 samples per variable drawn for 13 runs makes a browser page of tens of
megabytes; a screen shows at most a few thousand distinct x positions anyway. `thin` splits
the curve into equal runs of samples and keeps, from each, the sample with the smallest and the
one with the largest value (in time order), and always the first and the last sample: every peak
and every dip stays where it was, only samples between them are dropped. Used for drawing only;
tables and comparisons always use every sample.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DISPLAY_POINTS", "thin", "thin_indices"]

DISPLAY_POINTS = 2000  # points per drawn curve at most


def thin_indices(values: np.ndarray, limit: int = DISPLAY_POINTS) -> np.ndarray:
    """The indices (increasing) of at most `limit` samples of `values` that keep, for each of
    about limit/2 equal runs of samples, its smallest and its largest value, plus the first and
    the last sample. All indices when there are at most `limit` samples. A NaN is never chosen
    as an extreme of a run that has a finite value."""
    values = np.asarray(values, dtype=float)
    count = values.size
    if limit < 4:
        raise ValueError(f"limit must be at least 4 points, not {limit}")
    if count <= limit:
        return np.arange(count)
    buckets = (limit - 2) // 2
    interior = np.arange(1, count - 1)
    bucket = (interior - 1) * buckets // (count - 2)  # equal runs of the interior samples, 0 .. buckets-1
    low = np.where(np.isnan(values[interior]), np.inf, values[interior])
    high = np.where(np.isnan(values[interior]), -np.inf, values[interior])
    by_low = np.lexsort((interior, low, bucket))  # per bucket: smallest value first (earliest on ties)
    by_high = np.lexsort((interior, -high, bucket))  # per bucket: largest value first
    first = np.flatnonzero(np.r_[True, bucket[by_low][1:] != bucket[by_low][:-1]])
    kept = np.concatenate(([0, count - 1], interior[by_low[first]], interior[by_high[first]]))
    return np.unique(kept)


def thin(time: np.ndarray, values: np.ndarray, limit: int = DISPLAY_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """(time, values) thinned to at most `limit` points for drawing (`thin_indices`)."""
    kept = thin_indices(values, limit)
    return np.asarray(time)[kept], np.asarray(values)[kept]
