"""A lag of the friction behind the velocity: the competing explanation of a torque delay on the moving samples.

A torque logged late against the motion (a delay of the signal) shifts the whole measured torque: the
inertial torque ``J a``, the gravity torque and the friction alike. Friction that follows the velocity with
a lag of its own (the bristles' presliding dynamics of LuGre and Dahl: after a change of speed the friction
takes a travel of the order of the bristle deflection to reach its new level; frictional memory) shifts
only the friction. On a log whose rate hardly resolves the transients both leave a residual that a shift
of the torque by a sample or two reduces (foreign seed 307721, a clean work program at 131 Hz: a 1.8-sample
torque shift cut the moving samples' held-out RMS from 2.59 to 2.10 N m, the velocity map taken one sample
earlier to 2.01). A delay is a delay only where shifting the whole torque beats shifting the friction map
alone (:func:`friction_lag_heldout`, the competitor :func:`frictid.diagnose.chain` judges it against).

The lag's model on the moving samples: the velocity-only map of :func:`frictid.diagnose.signals._delay_columns`
(per sign 1, sqrt|w|, |w|, w^2) at the velocity ``L`` samples earlier, with the inertia and gravity
corrections at the sample itself, fitted by least squares to the friction torque; ``L`` chosen per fold on
the training folds among whole samples up to twice the delay found (:data:`LAG_GRID` at most).
"""
from __future__ import annotations

import math

import numpy as np

from ..data import finite
from .samples import Samples
from .signals import BATCH_ROWS, _delay_columns, _fold_blocks, _moving_groups, _moving_rows, delay_limit, shifted_torque

#: Most lags tried (whole samples, 1 to twice the delay found; geometric when there are more).
LAG_GRID = 12
#: Columns of the velocity map in :func:`frictid.diagnose.signals._delay_columns` (the rest are the rigid
#: body's: the acceleration, cos q and sin q, taken at the sample itself).
MAP_COLUMNS = 8


def lag_grid(S: Samples, delay_s: float) -> list[float]:
    """The lags [s] tried: whole sample periods from one to twice ``delay_s`` [s] (at least one, at most the
    delay search's own limit), :data:`LAG_GRID` of them at most, spaced geometrically when there are more."""
    dt = S.dt(0)
    kmax = max(1, min(int(round(2.0 * abs(delay_s) / dt)), int(delay_limit(S) / dt)))
    ks = sorted({int(round(v)) for v in np.geomspace(1, kmax, min(kmax, LAG_GRID))})
    return [k * dt for k in ks]


def _lag_columns(S: Samples, i: int, k: np.ndarray, lag_s: float, X0: np.ndarray) -> np.ndarray:
    """The lag model's columns at samples k of log i: the velocity map at ``lag_s`` [s] earlier, the rigid
    body's columns (of ``X0``, :func:`_delay_columns` at k) at the samples themselves."""
    L = int(round(lag_s / S.dt(i)))
    if L == 0:
        return X0
    X = _delay_columns(S, i, np.clip(k - L, 0, S.logs[i].n - 1))
    X[:, MAP_COLUMNS:] = X0[:, MAP_COLUMNS:]
    return X


def _lag_sums(S: Samples, lags: list[float]):
    """Per lag (0 first, then ``lags``) and fold: X'X and X'y of the moving samples, y the friction torque,
    X :func:`_lag_columns`; and y'y per fold. One pass over the moving samples."""
    allg = [0.0] + list(lags)
    nf = S.n_folds
    XtX = XtY = None
    yty = np.zeros(nf)
    for i, (km, fk) in enumerate(_moving_rows(S)):
        lg = S.logs[i]
        for g, k in _fold_blocks(km, fk, BATCH_ROWS):
            X0 = _delay_columns(S, i, k)
            y = finite(lg.F[k])
            if XtX is None:
                XtX = np.zeros((len(allg), nf, X0.shape[1], X0.shape[1]))
                XtY = np.zeros((len(allg), nf, X0.shape[1]))
            for n, lag in enumerate(allg):
                X = _lag_columns(S, i, k, lag, X0)
                XtX[n, g] += X.T @ X
                XtY[n, g] += X.T @ y
            yty[g] += float(y @ y)
    return allg, XtX, XtY, yty


def _solve(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    sc = np.sqrt(np.maximum(np.diag(A), 1e-300))
    return (np.linalg.pinv(A / np.outer(sc, sc), rcond=1e-10, hermitian=True) @ (b / sc)) / sc


def friction_lag_heldout(S: Samples, delay_s: float) -> dict | None:
    """The friction's lag judged on every moving sample as the delay is
    (:func:`frictid.diagnose.signals.delay_heldout`): per fold the lag (:func:`lag_grid`) and the map chosen
    on the other folds predict the held-out fold's friction torque. Returns the lag per fold [s], the
    held-out RMS without a lag and with it, and per held-out group (the nearest sliding sample's) the sums of
    the squared residuals without (``ss0``) and with the lag (``ss1``); None without moving samples."""
    allg, XtX, XtY, yty = _lag_sums(S, lag_grid(S, delay_s))
    if XtX is None:
        return None
    nf = S.n_folds
    fits = []
    for f in range(nf):
        tr = [g for g in range(nf) if g != f]
        best = None
        for n in range(len(allg)):
            A, b = XtX[n, tr].sum(0), XtY[n, tr].sum(0)
            beta = _solve(A, b)
            rss = float(yty[tr].sum() - beta @ b)
            if n == 0:
                beta0 = beta
            elif best is None or rss < best[0]:
                best = (rss, n, beta)
        fits.append((beta0, best[1], best[2]))
    ss0 = np.zeros(S.n_groups)
    ss1 = np.zeros(S.n_groups)
    for i, ((km, fk), gk) in enumerate(zip(_moving_rows(S, True), _moving_groups(S, True))):
        lg = S.logs[i]
        for g, k in _fold_blocks(km, fk, BATCH_ROWS):
            grp = _nearest_group(km, gk, k)
            X0 = _delay_columns(S, i, k)
            y = finite(lg.F[k])
            beta0, n, beta = fits[g]
            r0 = y - X0 @ beta0
            r1 = y - _lag_columns(S, i, k, allg[n], X0) @ beta
            ss0 += np.bincount(grp, weights=r0 * r0, minlength=S.n_groups)
            ss1 += np.bincount(grp, weights=r1 * r1, minlength=S.n_groups)
    n_mv = sum(km.size for km, _ in _moving_rows(S, True))
    return {"lags": [allg[n] for _, n, _ in fits], "rms_before": math.sqrt(ss0.sum() / max(n_mv, 1)),
            "rms_after": math.sqrt(ss1.sum() / max(n_mv, 1)), "ss0": ss0, "ss1": ss1}


def _nearest_group(km: np.ndarray, gk: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The held-out group of each of the moving samples k (a subset of km, whose groups are gk)."""
    return gk[np.searchsorted(km, k)]


# -- the delay where the friction's memory does not act: the faster half of the moving samples ------------

def _fast_rows(S: Samples) -> list:
    """Per log: (indices of its moving samples at least as fast as the median speed of all moving samples,
    their fold, their held-out group): the moves at speed, their accelerations and decelerations included,
    without the starts and reversals (cached)."""
    def compute():
        rows = _moving_rows(S, True)
        speeds = [np.abs(S.log_w(i)[km]) for i, (km, _) in enumerate(rows)]
        allv = np.concatenate(speeds) if speeds else np.zeros(0)
        if not allv.size:
            return []
        v_half = float(np.median(allv))
        out = []
        for (km, fk), gk, v in zip(rows, _moving_groups(S, True), speeds):
            sel = v >= v_half
            out.append((km[sel], fk[sel], gk[sel]))
        return out
    return S.cached("fast_moving_rows", compute)


def _fast_sums(S: Samples, whole: list[int]):
    """Per fold over the faster moving samples (:func:`_fast_rows`): X'X of the delay's columns
    (:func:`_delay_columns`) and, per shift in whole samples (``whole``), X'y with y the friction torque,
    the measured torque taken that many samples earlier. None without such samples."""
    nf = S.n_folds
    XtX = XtY = None
    for lg, tau, _, _, g, k, X in _fast_blocks(S):
        if XtX is None:
            XtX = np.zeros((nf, X.shape[1], X.shape[1]))
            XtY = np.zeros((len(whole), nf, X.shape[1]))
        XtX[g] += X.T @ X
        for n, L in enumerate(whole):
            XtY[n, g] += X.T @ (lg.F[k] - tau[k] + shifted_torque(tau, k.astype(float), L))
    return XtX, XtY


def _fast_blocks(S: Samples):
    """The faster moving samples (:func:`_fast_rows`) in batches of one fold: per batch the log, its finite
    torque, the log's faster rows and their groups, the fold, the batch's rows and the delay's columns
    (:func:`_delay_columns`) there."""
    for i, (km, fk, gk) in enumerate(_fast_rows(S)):
        if not km.size:
            continue
        lg = S.logs[i]
        tau = finite(lg.tau)
        for g, k in _fold_blocks(km, fk, BATCH_ROWS):
            yield lg, tau, km, gk, g, k, _delay_columns(S, i, k)


def delay_at_speed(S: Samples, shifts: list[float], centre: float | None = None) -> dict | None:
    """The delay judged on the faster half of the moving samples only (:func:`_fast_rows`), as
    :func:`frictid.diagnose.signals.delay_heldout` judges it on all of them: per fold the delay's map (per sign
    1, sqrt|w|, |w|, w^2, the acceleration, cos q, sin q) fitted on the other folds' faster samples with the
    torque shifted by the fold's shift (whole samples) and without, both predicting the held-out fold's.
    A delay of the signal shifts the torque at every speed (in the accelerations and decelerations at speed
    too); the friction's own memory (presliding at the starts and reversals, a loop holding the joint in
    its static band while its integrator builds up the torque) lives at the lowest speeds of each move. Returns
    the held-out RMS without and with the shift and per held-out group the sums of ``r_before^2 - r_after^2``
    (``d``); None without such samples. ``centre`` [s] given: a fraction of a sample judged against its
    mirror image about it instead of no shift, both interpolated
    (:func:`frictid.diagnose.signals.delay_mirror`); ``d`` then sums ``r_mirror^2 - r_shift^2``."""
    dt = S.dt(0)
    if centre is None:
        per_fold = [int(round(float(x) / dt)) for x in shifts]
        base = [0] * len(per_fold)
    else:
        per_fold = [float(x) / dt for x in shifts]
        base = [2.0 * centre / dt - x for x in per_fold]
    whole = sorted(set(base + per_fold))
    XtX, XtY = _fast_sums(S, whole)
    if XtX is None:
        return None
    nf = S.n_folds
    fits = []
    for f in range(nf):
        tr = [g for g in range(nf) if g != f]
        A = XtX[tr].sum(0)
        # the no-shift fit: the first row of sums as since session 20 (the smallest shift's when a fold's whole
        # shift is negative: docs/diagnosis.md "A delay under half a sample period", left for a card of its own)
        b0 = 0 if centre is None else whole.index(base[f])
        fits.append((_solve(A, XtY[b0, tr].sum(0)), _solve(A, XtY[whole.index(per_fold[f]), tr].sum(0))))
    d = np.zeros(S.n_groups)
    ss0 = ss1 = 0.0
    n = 0
    for lg, tau, km, gk, g, k, X in _fast_blocks(S):
        grp = _nearest_group(km, gk, k)
        b0, b1 = fits[g]
        r0 = lg.F[k] - X @ b0
        if centre is not None:
            r0 = r0 - tau[k] + shifted_torque(tau, k.astype(float), base[g])
        r1 = lg.F[k] - tau[k] + shifted_torque(tau, k.astype(float), per_fold[g]) - X @ b1
        d += np.bincount(grp, weights=r0 * r0 - r1 * r1, minlength=S.n_groups)
        ss0 += float(r0 @ r0)
        ss1 += float(r1 @ r1)
        n += k.size
    return {"rms_before": math.sqrt(ss0 / max(n, 1)), "rms_after": math.sqrt(ss1 / max(n, 1)), "d": d, "n": n}
