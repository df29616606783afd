"""Run-length helpers on boolean masks and label arrays (vectorised; no per-sample Python loops), moving
means and slopes, and the chunks that elementwise tests on a whole log run in (:func:`chunks`).

One loop is compiled: the prefix sum that every moving slope works from (:func:`prefix_sum`). numpy's
``cumsum`` of float64 runs several times slower than a plain compiled loop adding in the same order (the
same sums, bit for bit; :func:`prefix_sum_ref` is the numpy twin the tests compare with).
"""
from __future__ import annotations

import numpy as np
from numba import njit, types as nt
from scipy.ndimage import uniform_filter1d

#: :func:`paint` slices run by run up to this many runs, or one run per this many samples (a slice costs
#: about as much as a pass over that many samples).
FEW_RUNS = 64
SAMPLES_PER_RUN = 256
#: Samples per chunk of an elementwise threshold test (:func:`chunks`): its float temporaries are 512 KB
#: instead of the log's length (29 MB each on a joint-hour), and stay in the cache.
CHUNK = 1 << 16


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


def closed_runs(mask: np.ndarray, max_gap: int, min_len: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) of the runs of True in ``mask`` once the gaps shorter than ``max_gap``
    samples between them are closed and the runs shorter than ``min_len`` dropped:
    ``runs(drop_short(fill_short(mask, max_gap, False), min_len))`` without the two masks."""
    s, e = runs(mask)
    if s.size > 1:
        join = (s[1:] - e[:-1]) < max_gap
        s = s[np.concatenate(([True], ~join))]
        e = e[np.concatenate((~join, [True]))]
    long = (e - s) >= min_len
    return s[long], e[long]


def paint(arr: np.ndarray, starts: np.ndarray, ends: np.ndarray, value) -> None:
    """Set ``arr[s:e] = value`` for every run, in place, without a Python loop over samples (a loop over
    the runs when they are few: one slice each, instead of passes over the whole array)."""
    starts = np.asarray(starts, dtype=np.int64)
    ends = np.asarray(ends, dtype=np.int64)
    keep = ends > starts
    starts, ends = starts[keep], ends[keep]
    if starts.size == 0:
        return
    few = starts.size <= max(FEW_RUNS, arr.size // SAMPLES_PER_RUN)
    if few or not (arr.dtype == bool or np.isscalar(value)):
        for s, e in zip(starts.tolist(), ends.tolist()):
            arr[s:e] = value
        return
    delta = np.zeros(arr.size + 1, dtype=np.int32 if starts.size < 2**31 else np.int64)  # runs covering
    np.add.at(delta, starts, 1)
    np.add.at(delta, ends, -1)
    arr[np.cumsum(delta[:-1], dtype=delta.dtype) > 0] = value


def chunks(n: int, size: int | None = None):
    """Slices of ``size`` samples (default :data:`CHUNK`) covering ``range(n)``, in order: an elementwise
    expression computed chunk by chunk gives the same values without full-length temporaries."""
    size = size or CHUNK
    return (slice(a, min(a + size, n)) for a in range(0, n, size))


def count_prefix(mask: np.ndarray) -> np.ndarray:
    """``c[k]`` = number of True in ``mask[:k]`` (``n + 1`` values), so a window ``[a, b)`` holds
    ``c[b] - c[a]``. int32 when that holds the count (a bool to int64 cumulative sum is several times
    slower)."""
    m = np.asarray(mask, dtype=bool)
    c = np.zeros(m.size + 1, dtype=np.int32 if m.size < 2**31 else np.int64)
    np.cumsum(m, dtype=c.dtype, out=c[1:])
    return c


def any_in_runs(mask: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """For each run ``[s, e)`` (non-empty, in order, not overlapping), whether ``mask[s:e]`` holds a True."""
    m = np.asarray(mask, dtype=bool)
    starts = np.asarray(starts, dtype=np.int64)
    if starts.size == 0:
        return np.zeros(0, dtype=bool)
    bounds = np.empty(2 * starts.size, dtype=np.int64)
    bounds[0::2] = starts
    bounds[1::2] = ends
    if bounds[-1] >= m.size:  # the last run ends with the mask: its reduction runs to the end unbounded
        bounds = bounds[:-1]
    return np.logical_or.reduceat(m, bounds)[0::2]


def box_mean(x: np.ndarray, h: int) -> np.ndarray:
    """Centred moving mean over ``h`` samples (edges: nearest), O(n) whatever ``h``."""
    return uniform_filter1d(np.asarray(x, dtype=float), size=max(1, int(h)), mode="nearest")


def prefix_sum(x: np.ndarray) -> np.ndarray:
    """``c[k]`` = sum of ``x[:k] - x[0]`` (``n + 1`` values; offset by the first sample to keep the sums
    small): what :func:`box_slope` works from, computed once for several window lengths. Equal, bit for
    bit, to :func:`prefix_sum_ref`."""
    x = np.ascontiguousarray(x, dtype=float)
    c = np.empty(x.size + 1)
    c[0] = 0.0
    if x.size:
        _offset_cumsum(x, c)
    return c


def prefix_sum_ref(x: np.ndarray) -> np.ndarray:
    """:func:`prefix_sum` in numpy."""
    x = np.asarray(x, dtype=float)
    c = np.empty(x.size + 1)
    c[0] = 0.0
    if x.size:
        np.cumsum(x - x[0], out=c[1:])
    return c


@njit(cache=True)
def _offset_cumsum(x, c):  # pragma: no cover - compiled
    """``c[k + 1] = c[k] + (x[k] - x[0])``, in order (as ``np.cumsum(x - x[0])`` adds)."""
    x0 = x[0]
    acc = 0.0
    for k in range(x.size):
        acc += x[k] - x0
        c[k + 1] = acc


#: The kernel with its signature (numba types), for :func:`frictid.api.compile_kernels`.
KERNELS = ((_offset_cumsum, (nt.float64[::1], nt.float64[::1])),)


def box_slope(x: np.ndarray, h: int, dt: float, c: np.ndarray | None = None) -> np.ndarray:
    """Slope [x/s] at each sample: mean of the ``h`` samples after it minus mean of the ``h`` samples
    before it, over ``h dt`` (fewer samples near the ends). Noise: ``sigma sqrt(2/h) / (h dt)`` for white
    noise ``sigma``. O(n) whatever ``h``. ``c``: :func:`prefix_sum` of ``x`` when the caller has it."""
    h = max(1, int(h))
    n = np.size(x) if c is None else c.size - 1
    out = np.zeros(n)
    if n < 2:
        return out
    if c is None:
        c = prefix_sum(x)
    if n > 2 * h:
        # interior: full windows on both sides, plain slices (no index arrays); the sum of the h samples
        # after sample i is the sum before sample i + h: one array of window sums serves both, chunk by
        # chunk (for the whole log it was 29 MB more at the segmentation's peak on a joint-hour, and a
        # slope 6 -> 4.5 ms); a chunk of at least 8 h recomputes at most an eighth more sums
        mid = out[h:n - h + 1]
        for k in chunks(mid.size, max(CHUNK, 8 * h)):
            a, b = k.start, k.stop
            sums = np.subtract(c[a + h:b + 2 * h], c[a:b + h])  # sums[j] = c[a + j + h] - c[a + j]
            np.subtract(sums[h:], sums[:b - a], out=mid[k])
            mid[k] /= h * h * dt
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
