"""Run-length helpers on boolean masks and label arrays (vectorised; no per-sample Python loops)."""
from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d


def runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) indices of the runs of True in ``mask``."""
    m = np.asarray(mask, dtype=bool)
    if m.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    change = np.flatnonzero(m[1:] != m[:-1]) + 1
    edges = np.concatenate(([0], change, [m.size]))
    first_true = bool(m[0])
    starts = edges[0 if first_true else 1::2]
    ends = edges[1 if first_true else 2::2]
    k = min(starts.size, ends.size)
    return starts[:k].astype(np.int64), ends[:k].astype(np.int64)


def label_runs(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Start, end (exclusive) and value of each run of equal values in ``labels``."""
    x = np.asarray(labels)
    if x.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), x[:0]
    change = np.flatnonzero(x[1:] != x[:-1]) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [x.size]))
    return starts, ends, x[starts]


def fill_short(mask: np.ndarray, max_len: int, value: bool) -> np.ndarray:
    """Copy of ``mask`` where runs of ``value`` shorter than ``max_len`` samples that are bounded on both
    sides are flipped (closing small gaps when ``value`` is False, removing specks when True)."""
    m = np.asarray(mask, dtype=bool).copy()
    s, e = runs(m == value)
    inner = (s > 0) & (e < m.size) & ((e - s) < max_len)
    if inner.any():
        paint(m, s[inner], e[inner], not value)
    return m


def drop_short(mask: np.ndarray, min_len: int) -> np.ndarray:
    """Copy of ``mask`` without the runs of True shorter than ``min_len`` samples."""
    m = np.asarray(mask, dtype=bool).copy()
    s, e = runs(m)
    short = (e - s) < min_len
    if short.any():
        paint(m, s[short], e[short], False)
    return m


def paint(arr: np.ndarray, starts: np.ndarray, ends: np.ndarray, value) -> None:
    """Set ``arr[s:e] = value`` for every run, in place, without a Python loop over samples."""
    starts = np.asarray(starts, dtype=np.int64)
    ends = np.asarray(ends, dtype=np.int64)
    keep = ends > starts
    starts, ends = starts[keep], ends[keep]
    if starts.size == 0:
        return
    if arr.dtype == bool or np.isscalar(value):
        delta = np.zeros(arr.size + 1, dtype=np.int64)
        np.add.at(delta, starts, 1)
        np.add.at(delta, ends, -1)
        cover = np.cumsum(delta[:-1]) > 0
        arr[cover] = value
    else:  # pragma: no cover - not used
        for s, e in zip(starts, ends):
            arr[s:e] = value


def box_mean(x: np.ndarray, h: int) -> np.ndarray:
    """Centred moving mean over ``h`` samples (edges: nearest), O(n) whatever ``h``."""
    return uniform_filter1d(np.asarray(x, dtype=float), size=max(1, int(h)), mode="nearest")


def box_slope(x: np.ndarray, h: int, dt: float) -> np.ndarray:
    """Slope [x/s] at each sample: mean of the ``h`` samples after it minus mean of the ``h`` samples
    before it, over ``h dt`` (fewer samples near the ends). Noise: ``sigma sqrt(2/h) / (h dt)`` for white
    noise ``sigma``. O(n) whatever ``h``."""
    h = max(1, int(h))
    x = np.asarray(x, dtype=float)
    n = x.size
    out = np.zeros(n)
    if n < 2:
        return out
    c = np.empty(n + 1)
    c[0] = 0.0
    np.cumsum(x - x[0], out=c[1:])
    if n > 2 * h:
        # interior: full windows on both sides, plain slices (no index arrays)
        before = c[h:n - h + 1] - c[0:n - 2 * h + 1]
        after = c[2 * h:n + 1] - c[h:n - h + 1]
        out[h:n - h + 1] = (after - before) / (h * h * dt)
    if n > 2 * h:
        i = np.concatenate((np.arange(0, h), np.arange(n - h + 1, n)))
    else:
        i = np.arange(n)
    lo = np.clip(i - h, 0, n)
    hi = np.clip(i + h, 0, n)
    before = (c[i] - c[lo]) / np.maximum(i - lo, 1)
    after = (c[hi] - c[i]) / np.maximum(hi - i, 1)
    span = 0.5 * ((hi - i) + (i - lo)) * dt
    out[i] = (after - before) / np.maximum(span, dt)
    return out


def window_sum(x: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Sum of ``x[s:e]`` for each run (cumulative-sum based)."""
    c = np.concatenate(([0.0], np.cumsum(np.asarray(x, dtype=float))))
    return c[np.asarray(ends)] - c[np.asarray(starts)]
