"""Change points of one quantity over a joint's runs: any number of steps and wear episodes.

The series is modelled as segments between change points; each segment is flat or drifts linearly (wear),
and at each change point the level jumps (a step: a repair, a re-lubrication, a fault) or stays continuous
(the drift starts, ends or changes rate). Runs are weighted by their own noise ``s_i``
(:func:`run_noise`), so a change must stand clear of both the runs' standard errors and the series' scatter.

1. **Where**: ``ruptures.Dynp`` (exact dynamic programme) with the ``linear`` cost (a line per segment,
   weighted least squares) gives the best 0, 1, ..., K change points (segments of at least 3 runs).
2. **What**: for each of these, every choice of flat/drifting segments and jump/continuous change points is
   fitted by weighted least squares and scored by chi^2 + 2 ln(n) p, with p the base level, one per change
   point (its location), one per jump and one per drift: twice BIC's penalty, as the single-change rule
   before it had (2 p ln n keeps chance breaks in noise out: for n = 30 a step must explain 20 units of
   chi^2 more than a constant). A change point that changes nothing (flat to flat, no jump) is not a model.
3. **Noise**: ``s_i = sqrt(tau^2 + se_i^2)`` with ``tau^2`` the scatter the runs' standard errors do not
   explain (robust: 1.4826 MAD of the day-to-day differences / sqrt 2, so a step, one difference, and
   wear, a constant offset of the differences, hardly move it). When the chosen explanation's residuals
   say the noise is larger (chi^2 / (n - p) > 1), every ``s_i`` is scaled up by that and the choice made
   again.

Changes reported: a **step** at each jump (its date: the first run at the new level) and **wear** at the
start of each drifting segment (its date: the last run before the drift; the first run when the series
drifts from its start).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
import ruptures

#: Fewest runs in a segment (a drifting one needs a residual degree of freedom).
MIN_SEGMENT = 3
#: Most change points looked for (the window of a trend holds a few maintenance events, not dozens).
MAX_CHANGES = 3


def run_noise(y: np.ndarray, stderr: np.ndarray) -> np.ndarray:
    """Per-run noise s_i [unit of y]: sqrt(tau^2 + se_i^2), tau^2 the scatter beyond the standard errors."""
    d = np.diff(y)
    scatter = 1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2) if len(d) else 0.0
    se = np.where(np.isfinite(stderr) & (stderr > 0), stderr, np.nan)
    med = float(np.nanmedian(se)) if np.isfinite(se).any() else 0.0
    tau2 = max(scatter**2 - med**2, 0.0)
    s = np.sqrt(tau2 + np.where(np.isfinite(se), se, med) ** 2)
    floor = max(scatter, med, 1e-12 * max(float(np.max(np.abs(y))), 1e-300))
    return np.where(s > 0, s, floor)


@dataclass
class Segmentation:
    """One explanation of a series: change points (first run of each new segment), per segment whether
    it drifts, per change point whether the level jumps; the fit and its score."""

    breaks: tuple[int, ...] = ()
    drifts: tuple[bool, ...] = (False,)
    jumps: tuple[bool, ...] = ()
    fitted: np.ndarray = field(default_factory=lambda: np.zeros(0))
    coef: np.ndarray = field(default_factory=lambda: np.zeros(0))
    chi2: float = math.inf
    p: int = 1
    score: float = math.inf


def design(n: int, breaks, drifts, jumps) -> np.ndarray:
    """Columns: the base level; per drifting segment its ramp (0 before, rising 1 per run inside from the
    run before its start, held after); per jump a unit step from its change point on."""
    x = np.arange(n, dtype=float)
    starts = (0, *breaks)
    ends = (*breaks, n)
    cols = [np.ones(n)]
    for s, (a, b) in enumerate(zip(starts, ends)):
        if drifts[s]:
            origin = a if s == 0 else a - 1
            cols.append(np.clip(x - origin, 0.0, b - 1 - origin))
    cols += [(x >= b).astype(float) for b, j in zip(breaks, jumps) if j]
    return np.column_stack(cols)


def candidates(y: np.ndarray, s: np.ndarray) -> list[tuple[int, ...]]:
    """The best 0..K change points by a line per segment (weighted), ruptures.Dynp."""
    n = len(y)
    kmax = min(MAX_CHANGES, n // MIN_SEGMENT - 1)
    out = [()]
    if kmax < 1:
        return out
    x = np.arange(n, dtype=float)
    signal = np.column_stack([y / s, 1.0 / s, x / s])
    algo = ruptures.Dynp(model="linear", min_size=MIN_SEGMENT, jump=1).fit(signal)
    for k in range(1, kmax + 1):
        try:
            out.append(tuple(algo.predict(n_bkps=k)[:-1]))
        except ruptures.exceptions.BadSegmentationParameters:
            break
    return out


def fit_one(y: np.ndarray, s: np.ndarray, breaks, drifts, jumps, pen: float, Z=None) -> Segmentation:
    """Weighted least squares of one explanation (``Z``: covariates every explanation carries, last)."""
    X = design(len(y), breaks, drifts, jumps)
    if Z is not None:
        X = np.column_stack([X, Z])
    coef, *_ = np.linalg.lstsq(X / s[:, None], y / s, rcond=None)
    f = X @ coef
    chi2 = float(np.sum(((y - f) / s) ** 2))
    p = X.shape[1] + len(breaks)
    return Segmentation(tuple(breaks), tuple(drifts), tuple(jumps), f, coef, chi2, p, chi2 + pen * p)


def structures(k: int, n: int):
    """Every explanation with k change points: segment 0 flat or drifting; then at each change point the
    level steps into a flat segment (a repair, a re-lubrication, a fault), or continuously a flat segment
    starts to drift (the onset of wear) or a drift stops. Not a drift changing its rate, nor a step into a
    drift (a step then wear has a flat segment between them): each would let noise be explained twice."""
    for drifts in itertools.product((False, True), repeat=k + 1):
        for jumps in itertools.product((False, True), repeat=k):
            ok = all((not drifts[i + 1] and (jumps[i] or drifts[i])) or (drifts[i + 1] and not drifts[i] and not jumps[i])
                     for i in range(k))
            if ok and n - (1 + sum(drifts) + sum(jumps)) >= 1:
                yield drifts, jumps


def refine(y: np.ndarray, s: np.ndarray, seg: Segmentation, pen: float, Z=None) -> Segmentation:
    """Move each change point of an explanation to its best run between its neighbours (a continuous
    change of slope sits where the segments' lines cross, not where a line per segment would break)."""
    n, best = len(y), seg
    for _ in range(3):
        moved = False
        for i in range(len(best.breaks)):
            lo = (best.breaks[i - 1] if i else 0) + MIN_SEGMENT
            hi = (best.breaks[i + 1] if i + 1 < len(best.breaks) else n) - MIN_SEGMENT
            for b in range(lo, hi + 1):
                if b == best.breaks[i]:
                    continue
                breaks = best.breaks[:i] + (b,) + best.breaks[i + 1:]
                trial = fit_one(y, s, breaks, best.drifts, best.jumps, pen, Z)
                if trial.score < best.score - 1e-9:
                    best, moved = trial, True
        if not moved:
            break
    return best


def choose(y: np.ndarray, s: np.ndarray, cands, pen: float, Z=None, keep: int = 6) -> list[Segmentation]:
    """The explanations, best first: every structure on every candidate set of change points is scored,
    the best ``keep`` have their change points refined (:func:`refine`)."""
    scored = [fit_one(y, s, breaks, d, j, pen, Z) for breaks in cands for d, j in structures(len(breaks), len(y))]
    scored.sort(key=lambda g: g.score)
    return sorted((refine(y, s, g, pen, Z) if g.breaks else g for g in scored[:keep]), key=lambda g: g.score)


def segment(y: np.ndarray, stderr: np.ndarray, tc: np.ndarray | None = None,
            slope0: float = 0.0) -> tuple[Segmentation, np.ndarray, Segmentation]:
    """(the chosen explanation, the per-run noise it was chosen with, the best with no change).

    tc : the runs' temperature about their median [K] when the quantity is not normalised by a thermal
    law: every explanation then carries a term ``c tc`` (its coefficient last in ``coef``), so that the
    temperature is fitted together with the changes, not mistaken for them; ``slope0``, a first estimate
    of ``c`` (from the day-to-day differences), takes it out before the candidates are sought and the
    scatter is measured.
    """
    n = len(y)
    pen = 2.0 * math.log(n)
    y0 = y if tc is None else y - slope0 * tc
    # thermal laws multiply friction: a joint whose level stepped up by 30 % is 30 % more sensitive to
    # temperature, so the term is c tc times the level (the first-corrected values over their median)
    Z = None if tc is None else (tc * y0 / np.median(y0)).reshape(-1, 1)
    s = run_noise(y0, stderr)
    cands = candidates(y0, s)
    best = choose(y, s, cands, pen, Z)[0]
    # the noise is no less than what the chosen explanation leaves (chi^2 per degree of freedom)
    inflate = best.chi2 / max(n - best.p, 1)
    if inflate > 1.0:
        s = s * math.sqrt(inflate)
        best = choose(y, s, cands, pen, Z)[0]
    return best, s, fit_one(y, s, (), (False,), (), pen, Z)


def design_fit(seg: Segmentation) -> np.ndarray:
    """The explanation without its temperature term (the level and its changes)."""
    X = design(len(seg.fitted), seg.breaks, seg.drifts, seg.jumps)
    return X @ seg.coef[:X.shape[1]]


def changes_of(seg: Segmentation) -> list[dict]:
    """The steps and wear episodes of an explanation, in order: kind, index (run), size [unit of y]
    (a step: its jump; wear: the drift it accumulates over its segment)."""
    n = len(seg.fitted)
    starts, ends = (0, *seg.breaks), (*seg.breaks, n)
    coef = iter(seg.coef[1:])
    slopes = [next(coef) if d else 0.0 for d in seg.drifts]
    out = []
    for i, b in enumerate(seg.breaks):
        if seg.jumps[i]:
            out.append({"kind": "step", "index": int(b), "size": float(next(coef))})
    for s, (a, b) in enumerate(zip(starts, ends)):
        if seg.drifts[s]:
            onset = a if s == 0 else a - 1
            out.append({"kind": "wear", "index": int(onset), "size": float(slopes[s] * (b - 1 - onset))})
    return sorted(out, key=lambda c: (c["index"], c["kind"]))
