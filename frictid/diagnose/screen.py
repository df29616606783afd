"""Two-stage trials on long logs: a candidate judged on a stride of the samples first, and on all of them
only when it could pass.

A candidate enters the model only when it is significant and explains at least
:data:`frictid.diagnose.chain.EXPLAINED_MIN` of the friction RMS on held-out samples
(:meth:`frictid.diagnose.chain.Chain.worth_it`); a trial that cannot reach that bar changes nothing but its
own record. On a log of more than :data:`frictid.diagnose.search.STRIDE_MIN` sliding samples each candidate
is first judged by the same trial (its proposals, the folds' fits, the held-out groups) on the stride of
:class:`frictid.diagnose.search.StrideSearch` (every ``k``-th sample of every group, about
:data:`frictid.diagnose.search.STRIDE_TARGET` of them); what it explains there, ``E = sum_g d_g / n`` (``d_g``
the held-out group's sum of ``r_before^2 - r_after^2``, ``n`` the scored samples), estimates what it would
explain on all samples. The upper bound (:func:`explained_bound`) adds

- the sampling error of ``E``: ``z`` standard errors of the mean over the held-out groups (the groups as the
  units, as the chain's t test; ``z`` its one-sided quantile at the step's level ``ALPHA / m``). The stride
  keeps every group, so the stride's mean differs from the whole samples' by the variation within the
  groups only, which the spread between groups exceeds;
- the fits' share: the stride's folds fit the extension's coefficients (and its setting) on ``k`` times fewer
  samples, and a fit's held-out loss grows with the coefficients' variance, at most ``p rms_before^2 /
  G_train`` per sample (``p`` the term's coefficients and one setting, ``G_train`` the training folds'
  groups: every group one independent unit, the most the residual's correlation can make of it); where that
  share decides, the smaller of it and the stride's own in-sample to held-out gap (:func:`gap_allowance`,
  session 23), each of the two errors then at half the step's level.

Only a candidate whose bound is under the bar is skipped (and a delay only when it does not pay for itself on
every moving sample either, computed exactly); its record keeps the stride's numbers and the bound
(``screened``). A candidate that may pass is tried on all samples as before, so a choice, a name and every
number of a chosen or worthy candidate are the same as without the screen.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtri


def explained_bound(tr, n_scored: int, level: float, n_folds: int, fits: float | None = None) -> float:
    """Upper bound of the held-out RMS a candidate would explain on all samples, from its trial ``tr`` on the
    stride (:class:`frictid.diagnose.chain.Trial`: per-group ``d``, RMS before, coefficients ``k``) with
    ``n_scored`` scored samples and ``n_folds`` folds, at the one-sided ``level``; ``fits``: the fits' share
    (a mean square, :func:`gap_allowance`) instead of the one with every training group one unit."""
    d = np.asarray(tr.d, float)
    d = d[np.isfinite(d)]
    G = int(np.count_nonzero(d)) or 1   # groups with scored samples on the stride
    n = max(int(n_scored), 1)
    est = float(d.sum()) / n
    se = float(np.std(d, ddof=1)) * math.sqrt(d.size) / n if d.size > 1 else math.inf
    z = float(ndtri(1.0 - level))
    folds = max(int(n_folds), 2)
    if fits is None:
        fits = (tr.k + 1) * tr.rms_before ** 2 * folds / ((folds - 1) * G)
    return math.sqrt(max(est + z * se + fits, 0.0))


def gap_allowance(d_in: np.ndarray, d_out: np.ndarray, n_scored: int, level: float) -> float:
    """The fits' share of the bound from the stride's own fits: half the gap between what the candidate
    explains on its training samples and on held-out ones, plus ``z`` standard errors of it over the groups
    (``z`` at the one-sided ``level``). ``d_in``: per group, its sum of ``r_before^2 - r_after^2`` on the
    training sets that hold it (each fold's fits of the current model and of the extended one, averaged
    over those folds); ``d_out``: the held-out ``d``; ``n_scored``: the scored samples.

    Why half the gap. A fitted coefficient's error makes the training fit look better by about what it
    costs on held-out data (least squares: ``+p s^2`` and ``-p s^2``; a setting chosen on the training set
    adds to the first only), so half the gap estimates the held-out loss of the stride's fits. The trial
    on all samples fits the same groups with more samples each: its loss is at most the stride's (the
    variation within the groups averages out, the variation between them stays), so what it explains
    exceeds the stride's estimate by at most that loss. Sound where the residual is correlated over the
    groups too; the old share assumes every training group one independent unit at the residual's whole
    variance, and on a log whose residual is many times the bar it alone passed the bar (foreign seed 321021,
    1.4x)."""
    d_in, d_out = np.asarray(d_in, float), np.asarray(d_out, float)
    keep = np.isfinite(d_in) & np.isfinite(d_out) & ((d_in != 0) | (d_out != 0))
    g = d_in[keep] - d_out[keep]
    if g.size < 2:
        return math.inf
    n = max(int(n_scored), 1)
    se = float(np.std(g, ddof=1)) * math.sqrt(g.size) / n
    return max(0.5 * (float(g.sum()) / n + float(ndtri(1.0 - level)) * se), 0.0)


def screen_record(tr, stride, bound: float, bar: float) -> dict:
    """The record of a screened candidate (``selection.diagnosis.steps[].tested``): its trial's numbers on the
    stride and ``screened`` (the stride, its samples, the bound and the bar)."""
    rec = tr.record()
    rec["screened"] = {"stride": int(stride.sel[1] - stride.sel[0]) if stride.sel.size > 1 else 1,
                       "samples": int(stride.sub.n), "explained_bound": float(bound), "explained_min": float(bar)}
    return rec
