"""Held-out step functions of one variable: the training folds' mean residual in equal-count bins of it,
predicting the held-out fold. The competing explanation "some function of x" of the structure tests
(:mod:`.structure`) and of the temperature candidate's time course (:mod:`.chain`)."""
from __future__ import annotations

import numpy as np

from .samples import Samples

#: Bins of a variable: about this many samples per bin on average (at most MAX_BINS, at least MIN_BINS).
PER_BIN = 200
MAX_BINS, MIN_BINS = 120, 8


def equal_count_bins(x: np.ndarray, nb: int, side: str = "right") -> tuple[np.ndarray, int]:
    """Bin index per sample of ``nb`` bins of x of about equal count, and the number of bins: the edges are
    the quantiles ``k / nb`` of x (linear interpolation, equal edges merged: ties share a bin), a sample
    equal to an edge lies above it (``side="right"``) or below it (``"left"``): ``np.searchsorted(edges, x,
    side)``. The quantiles are read off a sorted copy (:func:`sorted_quantiles`; one vectorised sort costs
    less than numpy's selection of about 2 nb order statistics). Placing the sorted samples and scattering
    them back by an argsort costs more than the search on the bench log's variables (docs/diagnosis.md,
    "Benchmark", session 22)."""
    x = np.asarray(x)
    if x.size == 0:
        return np.zeros(0, np.intp), 1
    edges = np.unique(sorted_quantiles(np.sort(x), np.linspace(0, 1, nb + 1)[1:-1]))
    return np.searchsorted(edges, x, side=side), edges.size + 1


def sorted_quantiles(s: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``np.quantile(s, q)`` (linear interpolation) of an array ``s`` already sorted, to the bit: its two
    order statistics beside each virtual index ``(n - 1) q`` and numpy's interpolation between them, without
    numpy's copy and selection of them (a pass over the samples per call; session 23). NaNs (sorted last)
    leave it to numpy."""
    n = s.shape[0]
    if n == 0 or np.isnan(s[-1]):
        return np.quantile(s, q)
    vi = (n - 1) * np.asarray(q, dtype=float)
    lo = np.floor(vi).astype(np.intp)
    hi = lo + 1
    top = vi >= n - 1
    lo[top], hi[top] = -1, -1
    lo[vi < 0], hi[vi < 0] = 0, 0
    a, b = s[lo], s[hi]
    g = vi - lo
    d = b - a
    out = a + d * g
    np.subtract(b, d * (1 - g), out=out, where=g >= 0.5)
    return out


def _bins(x: np.ndarray, nb: int) -> np.ndarray:
    """Bin index per sample: ``nb`` bins of about equal count (ties share a bin)."""
    return equal_count_bins(x, nb)[0]


#: Variables whose bins are kept (the last ones binned: the time is binned by a structure test and by the
#: time-course confound check of every candidate that has one).
KEEP_BINS = 3


def _bins_of(S: Samples, x: np.ndarray, nb: int) -> np.ndarray:
    """:func:`_bins` of x, kept for the last :data:`KEEP_BINS` variables (x compared value by value: a
    variable formed again, ``S.th * 3600``, is found)."""
    kept = S.cached("binned_kept", lambda: [])
    for i, (x0, nb0, b) in enumerate(kept):
        # the first and last values tell most other variables apart without a pass over the samples
        if (nb0 == nb and x0.shape == x.shape and (x0.size == 0 or x0[0] == x[0] and x0[-1] == x[-1])
                and np.array_equal(x0, x)):
            kept.insert(0, kept.pop(i))
            return b
    b = _bins(x, nb)
    b = b.astype(np.min_scalar_type(max(int(b.max()), 0))) if b.size else b
    kept.insert(0, (x.copy(), nb, b))
    del kept[KEEP_BINS:]
    return b


def fold_parts(S: Samples) -> list:
    """Each fold's samples: a slice when the samples are ordered by fold (:func:`.samples._fold_major`), else
    a mask (cached)."""
    def compute():
        f = S.fold
        if f.size and np.any(np.diff(f) < 0):
            return [f == k for k in range(S.n_folds)]
        b = np.concatenate([[0], np.cumsum(np.bincount(f, minlength=S.n_folds))])
        return [slice(int(b[k]), int(b[k + 1])) for k in range(S.n_folds)]
    return S.cached("fold_parts", compute)


def heldout_binned(S: Samples, r: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The held-out prediction of r by the training folds' mean of r in bins of x (0 in a bin without
    training samples)."""
    nb = int(np.clip(S.n // PER_BIN, MIN_BINS, MAX_BINS))
    return heldout_cells(S, r, _bins_of(S, x, nb))


def heldout_cells(S: Samples, r: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The held-out prediction of r by the training folds' mean of r in the cells b (cell index per sample;
    0 in a cell without training samples)."""
    m = int(b.max()) + 1
    parts = fold_parts(S)
    cnts = np.array([np.bincount(b[te], minlength=m) for te in parts])
    sums = np.array([np.bincount(b[te], weights=r[te], minlength=m) for te in parts])
    pred = np.empty(S.n)
    for f, te in enumerate(parts):
        s, c = sums.sum(0) - sums[f], cnts.sum(0) - cnts[f]
        mean = np.where(c > 0, s / np.maximum(c, 1), 0.0)
        pred[te] = mean[b[te]]
    return pred
