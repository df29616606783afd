"""Held-out step functions of one variable: the training folds' mean residual in equal-count bins of it,
predicting the held-out fold. The competing explanation "some function of x" of the structure tests
(:mod:`.structure`) and of the temperature candidate's time course (:mod:`.chain`)."""
from __future__ import annotations

import numpy as np

from .samples import Samples

#: Bins of a variable: about this many samples per bin on average (at most MAX_BINS, at least MIN_BINS).
PER_BIN = 200
MAX_BINS, MIN_BINS = 120, 8


def _bins(x: np.ndarray, nb: int) -> np.ndarray:
    """Bin index per sample: ``nb`` bins of about equal count (ties share a bin)."""
    edges = np.unique(np.quantile(x, np.linspace(0, 1, nb + 1)[1:-1]))
    return np.searchsorted(edges, x, side="right")


def heldout_binned(S: Samples, r: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The held-out prediction of r by the training folds' mean of r in bins of x (0 in a bin without
    training samples)."""
    nb = int(np.clip(S.n // PER_BIN, MIN_BINS, MAX_BINS))
    b = _bins(x, nb)
    m = int(b.max()) + 1
    sums = np.array([np.bincount(b[S.fold == f], weights=r[S.fold == f], minlength=m) for f in range(S.n_folds)])
    cnts = np.array([np.bincount(b[S.fold == f], minlength=m) for f in range(S.n_folds)])
    pred = np.empty(S.n)
    for f in range(S.n_folds):
        s, c = sums.sum(0) - sums[f], cnts.sum(0) - cnts[f]
        mean = np.where(c > 0, s / np.maximum(c, 1), 0.0)
        te = S.fold == f
        pred[te] = mean[b[te]]
    return pred
