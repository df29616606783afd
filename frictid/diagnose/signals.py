"""Per-sample variables of the causes outside the friction model's own list, computed on the full logs and
taken at the sliding samples: the rests before each move (``dwell``) and the rate of the measured torque
(``delay``).

- **Dwell** (static friction that grows with the time spent at rest, Dieterich's contact ageing): the
  level factor's variable ``ln(1 + t_rest / t0) exp(-s / s_c)``, with ``t_rest`` the length of the rest
  (slower than the sliding speed ``v_min``) just before the current move (0 after a reversal without a
  rest), ``s`` the travel since the move started, ``t0`` and ``s_c`` chosen on training folds from scales
  of the data (the rests' durations, the moves' lengths).
- **Delay** between the torque and the motion: a torque logged ``d`` seconds ahead of the position and
  velocity leaves ``tau(t) - tau(t - d)`` in the friction residual. ``d`` is the shift of the torque that
  best fits the friction torque of every moving sample (transients included) by a velocity-only map with
  inertia and gravity corrections (:func:`delay_estimate`); the additive column at the sliding samples is
  the rate of the torque the motion explains over that shift, centred (:func:`delay_column`); its
  coefficient is the delay [s], positive when the torque leads the motion. The Savitzky-Golay rate of
  the measured torque (quadratic, over :data:`RATE_WINDOW` seconds) is what the structure tests use.
"""
from __future__ import annotations

import math
import weakref

import numpy as np

from ..data import finite
from .samples import Samples

#: Shortest rest [s] that counts (the edge left out at both ends of a run of sliding samples).
REST_MIN = 0.05
#: Window [s] of the Savitzky-Golay rate of the measured torque (at least 7 samples).
RATE_WINDOW = 0.025


def _moves(w: np.ndarray, v_min: float, k: np.ndarray):
    """The sign of the motion per sample of one log (0 at rest) and, at its samples ``k``, the start index of
    their run (at rest, or moving one way) and of the run before (-1 for the first run): looked up among the
    runs' starts, not spread over every sample of the log."""
    sg = np.where(np.abs(w) > v_min, np.sign(w), 0.0)
    edges = np.concatenate(([0], np.flatnonzero(sg[1:] != sg[:-1]) + 1))
    j = np.searchsorted(edges, k, side="right") - 1
    return sg, edges[j], np.where(j > 0, edges[np.maximum(j - 1, 0)], -1)


def rests(S: Samples) -> tuple[np.ndarray, np.ndarray]:
    """(t_rest [s], s [q]) at the sliding samples: the length of the rest before the current move (0 after a
    reversal without a rest) and the travel since the move started (cached)."""
    def compute():
        tr, sd = np.zeros(S.n), np.zeros(S.n)
        for i, lg in enumerate(S.logs):
            sel = S.li == i
            if not sel.any() or lg.q is None:
                continue
            k = S.k[sel]
            sg, st, pv = _moves(S.log_w(i), S.v_min, k)
            after = (st > 0) & (pv >= 0)
            after[after] &= sg[st[after] - 1] == 0
            tr[sel] = np.where(after, lg.t[st] - lg.t[np.maximum(pv, 0)], 0.0)
            q = finite(lg.q)
            sd[sel] = np.abs(q[k] - q[st])
        return tr, sd
    return S.cached("rests", compute)


def rest_scales(S: Samples) -> tuple[np.ndarray, np.ndarray] | None:
    """The settings tried for the dwell variable: ``t0`` [s] (the shortest and the median rest before a move)
    and ``s_c`` [q] (1 % to 30 % of the median travel of a move, 4 values); None when the moves follow
    fewer than 3 rests of at least two different lengths (nothing to tell a dwell effect by)."""
    return S.cached("rest_scales", lambda: _rest_scales(S))


def _rest_scales(S: Samples) -> tuple[np.ndarray, np.ndarray] | None:
    tr, sd = rests(S)
    # a rest shorter than the sliding samples' edge at the ends of a run (50 ms, samples.py) is a dip of
    # the measured velocity at a reversal, not a rest
    tr = np.where(tr >= REST_MIN, tr, 0.0)
    lengths = np.unique(np.round(tr[tr > 0], 6))
    if lengths.size < 2 or np.count_nonzero(tr > 0) < 3 or lengths.max() < 2 * lengths.min():
        return None
    travel = float(np.median(sd[tr > 0])) if np.any(tr > 0) else 0.0
    if travel <= 0:
        return None
    t0 = np.unique([float(lengths.min()), float(np.median(lengths))])
    return t0, np.geomspace(0.01, 0.3, 4) * 2 * travel


def dwell_state(S: Samples, t0: float, s_c: float) -> np.ndarray:
    """``ln(1 + t_rest / t0) exp(-s / s_c)`` at the sliding samples (rests shorter than :data:`REST_MIN`: 0)."""
    def scale():   # the rest's part, per t0 (the grid has two), and -s: cached, the same numbers
        tr, _ = rests(S)
        return np.log1p(np.where(tr >= REST_MIN, tr, 0.0) / t0)
    lt = S.cached(("dwell_rest", float(t0)), scale)
    out = np.divide(S.cached("dwell_minus_s", lambda: -rests(S)[1]), s_c)
    np.exp(out, out=out)
    np.multiply(lt, out, out=out)
    return out


def _log_rate(S: Samples, i: int) -> np.ndarray:
    """The measured torque's rate [F/s] at every sample of log i (cached)."""
    def compute():
        from scipy.signal import savgol_filter

        lg = S.logs[i]
        dt = S.dt(i)
        win = max(7, int(round(RATE_WINDOW / dt)) | 1)
        tau = finite(lg.tau)
        return savgol_filter(tau, win, 2, deriv=1, delta=dt) if lg.n > win else np.gradient(tau, dt)
    return S.cached(("torque_rate", i), compute)


def torque_rate(S: Samples) -> np.ndarray:
    """The measured torque's rate dtau/dt [F/s] at the sliding samples (cached)."""
    def compute():
        out = np.empty(S.n)
        for i in range(len(S.logs)):
            sel = S.li == i
            if sel.any():
                out[sel] = _log_rate(S, i)[S.k[sel]]
        return out
    return S.cached("torque_rate", compute)


# -- the delay between torque and motion, estimated on all moving samples ----------------------------------

#: Longest delay tried, as a share of the mean duration of a one-sign run of the motion (a delay longer
#: than that is no longer a shift of the torque against the same motion).
DELAY_MAX_RUN = 0.25
#: Moving samples: faster than this share of the top speed (as the excitation shares of the causes).
MOVING_FRACTION = 0.02
#: Rows per block of the moving samples' sums (bounded memory, one pass per shift).
BLOCK = 1 << 16


def shifted_torque(tau: np.ndarray, k: np.ndarray, shift: float) -> np.ndarray:
    """``tau`` at the (fractional) sample positions ``k - shift`` [samples], linearly interpolated, clipped
    to the log: the measured torque ``shift`` samples earlier."""
    j = k - shift
    j0 = np.clip(np.floor(j).astype(np.int64), 0, tau.size - 2)
    fr = np.clip(j - j0, 0.0, 1.0)
    return tau[j0] * (1.0 - fr) + tau[j0 + 1] * fr


def _nearest(k: np.ndarray, label: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The ``label`` of the sample of ``k`` (sample indices, any order) nearest to each of ``at`` (the
    earlier one on a tie)."""
    if k.size == 0:
        return np.zeros(at.size, np.int64)
    return label[_nearest_index(k, at)]


def _nearest_index(k: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The position in ``k`` (sample indices, any order, at least one) of the sample nearest to each of
    ``at`` (the earlier one on a tie): :func:`_nearest`'s search, which every label of the same samples
    shares (the moving samples' folds and groups: one sort and one search of them, not two)."""
    order = np.argsort(k)
    if k.size < 2:
        return np.zeros(at.size, np.intp)
    ks = k[order]
    j = np.clip(np.searchsorted(ks, at), 1, ks.size - 1)
    return order[np.where(np.abs(ks[j - 1] - at) <= np.abs(ks[j] - at), j - 1, j)]


def _labels_at(S: Samples, i: int, label: np.ndarray, km: np.ndarray, key) -> np.ndarray:
    """``label`` (a per-sample array of S) of log i's sample nearest in time to each of log i's moving
    samples ``km``, by the search of :func:`_nearest_index` kept under ``key`` for the next label asked."""
    sel = S.li == i
    one = bool(sel.all())
    idx = S.cached(key, lambda: _nearest_index(S.k if one else S.k[sel], km))
    return label[idx] if one else label[sel][idx]


#: Bristle lengths of travel after a reversal within which the friction's presliding state still acts:
#: from a full reversal the LuGre state closes on its sliding level as ``2 exp(-s / L)``, 1.3 % left at 5.
BRISTLE_SETTLED = 5.0


def settled(S: Samples, i: int) -> np.ndarray:
    """Per sample of log i: whether the travel since the velocity last changed sign (a reversal, or a start
    from rest) exceeds :data:`BRISTLE_SETTLED` bristle lengths of the fit's LuGre (``S.bristle``; all True
    without one, or without positions). Within it the friction's own state lags the motion, as a torque
    delay would: a delay estimated there takes the bristles' lag for its own (foreign card seed 316013, a
    7.5 ms delay at 109 Hz: estimated at 21.6 ms on every moving sample, 7.6 ms on those past 3 bristle
    lengths). Left out of the estimate only: the delay is judged on every moving sample
    (:func:`_moving_rows` ``every``; session 23, foreign seed 322527: a 50 ms delay lengthened the fit's
    bristles to 2.5 mrad, the plant's 0.23, and the travel past them held what the delay changes)."""
    lg = S.logs[i]
    if S.bristle is None or not S.bristle > 0 or lg.q is None:
        return np.ones(lg.n, bool)
    q = finite(np.asarray(lg.q, float))
    s = np.sign(S.log_w(i))
    start = np.zeros(lg.n, np.int64)
    turn = np.flatnonzero(s[1:] != s[:-1]) + 1
    start[turn] = turn
    start = np.maximum.accumulate(start)
    return np.abs(q - q[start]) > BRISTLE_SETTLED * S.bristle


def _moving_rows(S: Samples, every: bool = False) -> list:
    """Per log: (indices of its moving samples, their fold: that of the nearest sliding sample in time). The
    moving samples are faster than :data:`MOVING_FRACTION` of the top speed and, for the delay's estimate
    (``every`` False), past the bristles' travel after a reversal (:func:`settled`); ``every`` True: all of
    them, where a delay is judged (:func:`delay_heldout`)."""
    def compute():
        out = []
        for i, lg in enumerate(S.logs):
            w = S.log_w(i)
            m = (np.abs(w) > max(MOVING_FRACTION * S.w0, S.v_min)) & np.isfinite(lg.F) & np.isfinite(lg.tau)
            km = np.flatnonzero(m if every else m & settled(S, i))
            sel = S.li == i
            if km.size < 8 or not sel.any() or lg.n < 3:
                out.append((np.zeros(0, np.int64), np.zeros(0, np.int64)))
                continue
            out.append((km, _labels_at(S, i, S.fold, km, ("moving_nearest", every, i))))
        return out
    if every and (S.bristle is None or not S.bristle > 0):
        return _moving_rows(S)   # nothing left out: the same rows
    return S.cached("moving_rows_every" if every else "moving_rows", compute)


def _delay_columns(S: Samples, i: int, k: np.ndarray, trig: tuple | None = None) -> np.ndarray:
    """The velocity-only map and rigid-body corrections a delay must not stand in for, at samples k of log
    i: per sign 1, sqrt|w|, |w|, w^2; the acceleration (an inertia error); cos q, sin q (a gravity error).
    trig : (cos q, sin q) at k when the pass has them (:func:`_fold_trig`), else computed here."""
    w = S.log_w(i)[k]
    v = np.abs(w)
    sv, v2 = np.sqrt(v), v * v
    q = S.logs[i].q
    rot = S.axis_rotary and q is not None
    X = np.empty((11 if rot else 9, k.size))   # rows filled in place: the columns of the F-ordered X.T
    for r, m in ((0, w > 0), (4, w < 0)):
        X[r] = m
        np.multiply(m, sv, out=X[r + 1])
        np.multiply(m, v, out=X[r + 2])
        np.multiply(m, v2, out=X[r + 3])
    X[8] = S.log_a(i)[k]
    if rot and trig is not None:
        X[9], X[10] = trig
    elif rot:
        qk = finite(q[k])
        np.cos(qk, out=X[9])
        np.sin(qk, out=X[10])
    return X.T


def _delay_gram(S: Samples):
    """Per fold: X'X of the moving samples, X :func:`_delay_columns` (None without moving samples; cached).
    It does not depend on the shift: summed once, in the first pass of :func:`_delay_prefetch` (the columns
    it builds for the shifts' sums serve it too), for every shift tried (the largest share of their time,
    11 x 11 products per row against 11)."""
    if not S.has("delay_gram"):
        _delay_prefetch(S, [])
    return S.cached("delay_gram", lambda: None)


def _sums_key(shift_s: float) -> tuple:
    return ("delay_sums", round(float(shift_s), 12))


def _delay_sums(S: Samples, shift_s: float, rss: bool = True):
    """Per fold: (X'X, X'y, y'y) of the moving samples, ``y`` the friction torque with the measured torque
    taken ``shift_s`` seconds earlier (``F - tau(t) + tau(t - shift)``), X :func:`_delay_columns` (cached;
    X'X from :func:`_delay_gram`; several shifts at once by :func:`_delay_prefetch`). ``rss`` False: y'y
    may be NaN (a fraction of a sample's sums derived from its whole neighbours', :func:`_derived`)."""
    _delay_prefetch(S, [shift_s])
    key = _sums_key(shift_s)
    out = S.cached(key, lambda: None)
    if rss and out[2] is not None and np.isnan(out[2]).any():   # derived: summed over the moving samples
        S.forget(key)
        _delay_prefetch_pass(S, [key[1]])
        out = S.cached(key, lambda: None)
    return out


#: Rows per block of the sums of several shifts at once (:func:`_delay_prefetch`: a block's columns and its
#: shifted torques, rows x shifts, stay in cache).
BATCH_ROWS = 1 << 13
#: The ternary search of :func:`delay_estimate` fetches every shift of its interval at once when it spans at
#: most this many samples (a shift costs a gather and a product there, a pass of the search the columns).
PREFETCH_SPAN = 64


#: The moving samples of a log in fold order (:func:`_fold_order`), kept while their arrays live: id of the
#: folds' array -> (weak references to it and to the samples' array, the order).
_FOLD_ORDER: dict = {}


def _fold_order(km: np.ndarray, fk: np.ndarray) -> tuple:
    """(the samples km in fold order, their folds, the starts of the folds after the first). The rows are a
    log's cached moving samples (:func:`_moving_rows`, :func:`frictid.diagnose.lag._fast_rows`), and every
    pass over them (the delay search's shifts, its judgement, the lag's) reads them in this order: sorted
    once while they live, not on every pass (a stable sort of 1.7 M samples on the one-hour bench log)."""
    got = _FOLD_ORDER.get(id(fk))
    if got is not None and got[0]() is fk and got[1]() is km:
        return got[2]
    order = np.argsort(fk, kind="stable")
    fs = fk[order]
    out = (km[order], fs, np.flatnonzero(np.diff(fs)) + 1)
    _FOLD_ORDER[id(fk)] = (weakref.ref(fk), weakref.ref(km), out)
    weakref.finalize(fk, _FOLD_ORDER.pop, id(fk), None)
    return out


def _fold_blocks(km: np.ndarray, fk: np.ndarray, rows: int):
    """(fold, sample indices) of the moving samples km of one log, fold by fold, in blocks of at most
    ``rows`` (each fold's samples in their order in the log)."""
    ks = _fold_order(km, fk)[0]
    for g, b, e in _fold_spans(km, fk, rows):
        yield g, ks[b:e]


def _fold_spans(km: np.ndarray, fk: np.ndarray, rows: int):
    """(fold, start, end) of :func:`_fold_blocks`' blocks: their rows in the fold order of km
    (:func:`_fold_order`)."""
    _, fs, edges = _fold_order(km, fk)
    for s, e in zip(np.concatenate(([0], edges)), np.concatenate((edges, [fs.size]))):
        for b in range(s, e, rows):
            yield int(fs[s]), b, min(b + rows, e)


#: cos q and sin q of a log's moving samples in fold order (:func:`_fold_trig`), kept while their arrays
#: live: id of the folds' array -> (weak references to it and to the samples' array, the two rows).
_FOLD_TRIG: dict = {}


def _fold_trig(S: Samples, i: int, km: np.ndarray, fk: np.ndarray) -> np.ndarray | None:
    """cos q and sin q (two rows) at the moving samples km of log i in fold order (:func:`_fold_order`),
    None off a rotary axis: the gravity columns of :func:`_delay_columns`, which do not depend on the shift,
    formed once while the samples live, not on every pass of the delay search over them (two
    transcendental functions of 1.7 M positions per pass on the one-hour bench log). The same values: the
    same functions of the same positions."""
    q = S.logs[i].q
    if not (S.axis_rotary and q is not None):
        return None
    got = _FOLD_TRIG.get(id(fk))
    if got is not None and got[0]() is fk and got[1]() is km:
        return got[2]
    qk = finite(q[_fold_order(km, fk)[0]])
    out = np.empty((2, qk.size))
    np.cos(qk, out=out[0])
    np.sin(qk, out=out[1])
    _FOLD_TRIG[id(fk)] = (weakref.ref(fk), weakref.ref(km), out)
    weakref.finalize(fk, _FOLD_TRIG.pop, id(fk), None)
    return out


def _delay_prefetch(S: Samples, shifts) -> None:
    """:func:`_delay_sums` of every shift of ``shifts`` not yet cached, in one pass over the moving samples:
    the columns X of a block are computed once for all the shifts (they do not depend on the shift; only
    ``y`` does), each shift adding a gather of the torque and a product with X."""
    todo = sorted({_sums_key(s)[1] for s in shifts if not S.has(_sums_key(s))})
    _delay_prefetch_pass(S, [s for s in todo if not _derived(S, s)])


def _delay_prefetch_pass(S: Samples, todo: list) -> None:
    """The pass of :func:`_delay_prefetch` over the moving samples for the shifts ``todo`` (rounded keys,
    none cached), X'X with them when it is not cached."""
    gram = not S.has("delay_gram")   # X'X in the same pass, the first one
    if not todo and not gram:
        return
    nf, ns = S.n_folds, len(todo)
    XtX = None if gram else S.cached("delay_gram", lambda: None)
    XtY = None
    yty = np.zeros((nf, ns))
    for i, (km, fk) in enumerate(_moving_rows(S)):
        lg = S.logs[i]
        tau = finite(lg.tau)
        sh = np.asarray(todo) / S.dt(i)
        # whole samples (up to the rounding of the shift in seconds): the torque read, not interpolated
        whole = bool(np.all(np.abs(sh - np.round(sh)) < 1e-6))
        ks, trig = _fold_order(km, fk)[0], _fold_trig(S, i, km, fk)
        for g, b, e in _fold_spans(km, fk, BATCH_ROWS):
            k = ks[b:e]
            X = _delay_columns(S, i, k, None if trig is None else trig[:, b:e])
            if gram:
                if XtX is None:
                    XtX = np.zeros((nf, X.shape[1], X.shape[1]))
                XtX[g] += X.T @ X
            if not ns:
                continue
            if whole:   # shifted_torque at a whole shift, without its interpolation (the same numbers); the
                # indices clipped to the log by the gather itself, not in a copy of them
                Y = np.take(tau, k[:, None] - np.round(sh).astype(np.int64)[None, :], mode="clip")
            else:
                Y = shifted_torque(tau, k.astype(float)[:, None] - sh[None, :], 0.0)
            Y += (lg.F[k] - tau[k])[:, None]
            if XtY is None:
                XtY = np.zeros((nf, X.shape[1], ns))
            XtY[g] += X.T @ Y   # BLAS with one thread (frictid.diagnose.check: the diagnosis' own limit)
            yty[g] += np.einsum("ij,ij->j", Y, Y)
    if gram:
        S.cached("delay_gram", lambda: XtX)
    for n, s in enumerate(todo):
        val = (XtX, None if XtY is None else XtY[:, :, n].copy(), yty[:, n].copy())
        S.cached(("delay_sums", s), lambda v=val: v)


def _derived(S: Samples, shift_s: float) -> bool:
    """Cache the sums of a shift of a fraction of a sample from those of the two whole shifts around it, when
    both are cached (the search's parabola is fitted between them) and every log has one sample period:
    the interpolated torque is ``(1 - fr) y_c + fr y_(c-1)`` (``c`` the whole shift above, ``fr = c - shift``),
    so ``X'y`` is that combination of theirs (up to rounding; at the ends of a log both clip to the same
    sample), without a pass over the moving samples. ``y'y`` needs their cross product and is not derived:
    NaN (the fits at such shifts ask for the map only; :func:`_delay_sums` sums such a shift itself when
    y'y is asked for).
    Returns whether the sums are cached now."""
    dt = S.dt(0)
    if any(S.dt(i) != dt for i in range(1, len(S.logs))):
        return False
    sh = shift_s / dt
    if abs(sh - round(sh)) < 1e-6:
        return False
    c = math.ceil(sh)
    hi, lo = _sums_key(c * dt), _sums_key((c - 1) * dt)
    if not (S.has(hi) and S.has(lo)):
        return False
    XtX, a, _ = S.cached(hi, lambda: None)
    _, b, _ = S.cached(lo, lambda: None)
    if XtX is None or a is None or b is None:
        return False
    fr = c - sh
    val = (XtX, a * (1.0 - fr) + b * fr, np.full(XtX.shape[0], np.nan))
    S.cached(_sums_key(shift_s), lambda: val)
    return True


def _delay_fit(S: Samples, shift_s: float, folds, rss: bool = True):
    """(coefficients of :func:`_delay_columns`, residual sum of squares) of the least-squares fit of
    :func:`_delay_sums` on the given folds ((None, inf) without moving samples; ``rss`` False: the
    coefficients are what is asked for, the sum may be NaN)."""
    XtX, XtY, yty = _delay_sums(S, shift_s, rss)
    if XtX is None:
        return None, math.inf
    f = list(folds)
    A, b = XtX[f].sum(0), XtY[f].sum(0)
    sc = np.sqrt(np.maximum(np.diag(A), 1e-300))
    beta = np.linalg.pinv(A / np.outer(sc, sc), rcond=1e-10, hermitian=True) @ (b / sc)
    return beta / sc, float(yty[f].sum() - beta @ (b / sc))


def _delay_rss(S: Samples, shift_s: float, folds) -> float:
    return _delay_fit(S, shift_s, folds)[1]


def delay_map(S: Samples, shift_s: float, folds) -> tuple:
    """The coefficients of the velocity-only map with inertia and gravity corrections fitted with the delay
    (:func:`_delay_fit`), as a tuple (a term's setting)."""
    beta = _delay_fit(S, shift_s, folds, rss=False)[0]
    return () if beta is None else tuple(float(x) for x in beta)


def delay_estimates(S: Samples) -> list:
    """:func:`delay_estimate` of each fold's training folds (cached), and the moving samples' sums at those
    shifts fetched in one pass (each fold's map, :func:`delay_map`, is fitted at its own shift)."""
    def compute():
        nf = S.n_folds
        sets = [[g for g in range(nf) if g != f] for f in range(nf)]
        dt, kmax, grid = _delay_grid(S)
        _delay_prefetch(S, [g * dt for g in grid])
        # the samples between each set's best grid shift and its neighbours, for all sets in one pass
        near = set()
        for folds in sets:
            i = min(range(len(grid)), key=lambda n: _delay_rss(S, grid[n] * dt, folds))
            lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
            if hi - lo <= PREFETCH_SPAN:
                near.update(range(max(lo - 1, -kmax), min(hi + 1, kmax) + 1))
        _delay_prefetch(S, [g * dt for g in near])
        out = [delay_estimate(S, folds) for folds in sets]
        _delay_prefetch(S, out)
        return out
    return S.cached("delay_estimates", compute)


def _delay_grid(S: Samples) -> tuple[float, int, list]:
    """(sample period, longest shift in samples, the shifts first tried): 0, 1, 2, 3 samples and two per
    octave up to :func:`delay_limit`, of either sign."""
    dt = S.dt(0)
    kmax = max(1, int(delay_limit(S) / dt))
    pos = sorted({1, 2, 3} | {int(round(v)) for v in np.geomspace(1, kmax, max(2, int(2 * math.log2(kmax + 1))))})
    return dt, kmax, sorted({-g for g in pos if g <= kmax} | {0} | {g for g in pos if g <= kmax})


def delay_estimate(S: Samples, folds=None) -> float:
    """The delay [s] between the measured torque and the motion, positive when the torque leads: the shift
    of the torque that best fits the friction torque of every moving sample of the given folds (all when
    None) by a velocity-only map with inertia and gravity corrections (:func:`_delay_columns`). Shifts of
    0, 1, 2, 3 samples and two per octave up to :func:`delay_limit`, refined to the sample between the best
    one's neighbours (ternary search), then to a fraction of a sample by a parabola."""
    folds = tuple(range(S.n_folds)) if folds is None else tuple(folds)
    dt, kmax, grid = _delay_grid(S)
    rss: dict = {}

    def at(g: int) -> float:
        if g not in rss:
            rss[g] = _delay_rss(S, g * dt, folds)
        return rss[g]

    def fetch(gs) -> None:   # the sums of several shifts in one pass over the moving samples
        _delay_prefetch(S, [g * dt for g in gs if g not in rss])

    fetch(grid)
    best = min(grid, key=at)
    i = grid.index(best)
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    while hi - lo > 2:   # ternary search on the samples between the grid's neighbours of its best
        m1, m2 = lo + (hi - lo) // 3, hi - (hi - lo) // 3
        fetch(range(max(lo - 1, -kmax), min(hi + 1, kmax) + 1) if hi - lo <= PREFETCH_SPAN else (m1, m2))
        if at(m1) <= at(m2):
            hi = m2
        else:
            lo = m1
    fetch(range(max(lo - 1, -kmax), min(hi + 1, kmax) + 1))
    best = min(range(lo, hi + 1), key=at)
    if -kmax < best < kmax:
        a, b, c = at(best - 1), at(best), at(best + 1)
        den = a - 2 * b + c
        frac = 0.5 * (a - c) / den if den > 0 else 0.0
        return float((best + float(np.clip(frac, -0.5, 0.5))) * dt)
    return float(best * dt)


def _run_time(S: Samples) -> float:
    """Mean duration [s] of a run of one velocity sign (moving samples) over the logs."""
    def compute():
        total, runs = 0.0, 0
        for i, lg in enumerate(S.logs):
            w = S.log_w(i)
            m = np.abs(w) > MOVING_FRACTION * S.w0
            if m.sum() < 2:
                continue
            runs += 1 + int(np.count_nonzero(np.diff(np.sign(w[m]))))
            total += float(np.count_nonzero(m)) * S.dt(i)
        return total / runs if runs else 0.0
    return S.cached("run_time_moving", compute)


def _torque_features(S: Samples, i: int, j: np.ndarray) -> tuple:
    """What :func:`_torque_model` reads at samples j of log i, whatever its map: ``tau - F``, the speed
    |w|, its square root, the masks w > 0 and w < 0, the acceleration, cos q and sin q (None off a rotary
    axis)."""
    lg = S.logs[i]
    base = finite(lg.tau[j]) - finite(lg.F[j])
    w = S.log_w(i)[j]
    v = np.abs(w)
    trig = None
    q = S.logs[i].q
    if S.axis_rotary and q is not None:
        qk = finite(q[j])
        trig = (np.cos(qk), np.sin(qk))
    return base, v, np.sqrt(v), w > 0, w < 0, S.log_a(i)[j], trig


def _torque_model(feats: tuple, beta: tuple) -> np.ndarray:
    """The torque at the samples of ``feats`` (:func:`_torque_features`) as the motion explains it, free of
    the torque sensor's noise: ``J a + G`` (``tau - F``, in which the sensor's noise cancels) plus the delay
    fit's map and corrections (:func:`_delay_columns` times ``beta``, summed column by column without
    forming them)."""
    base, v, sv, pos, neg, a, trig = feats
    out = base.copy()
    if not beta:
        return out
    b = np.asarray(beta, float)
    for m, c in ((pos, b[0:4]), (neg, b[4:8])):
        out += m * (c[0] + c[1] * sv + c[2] * v + c[3] * v * v)
    out += b[8] * a
    if trig is not None and b.size > 9:
        out += b[9] * trig[0] + b[10] * trig[1]
    return out


def _column_key(shift_s: float, beta: tuple) -> tuple:
    return ("delay_column", round(float(shift_s), 12), beta)


def _ends(S: Samples, i: int, k: np.ndarray, shift_s: float, n: int) -> list:
    """The two ends ``k +- shift / 2`` [samples] of log i (n samples, k whole sample indices): (sample below,
    fraction) of each. The fraction is that of the half shift, one number for every sample, except where an
    end leaves the log (clipped there, per sample)."""
    h = 0.5 * shift_s / S.dt(i)
    out = []
    for hh in (h, -h):
        base = math.floor(hh)
        j0 = k + base
        fr = hh - base
        bad = (j0 < 0) | (j0 > n - 2)
        if bad.any():   # clipped to the log: the fraction per sample
            pos = k[bad] + hh
            jb = np.clip(np.floor(pos).astype(np.int64), 0, n - 2)
            j0[bad] = jb
            frs = np.full(k.size, fr)
            frs[bad] = np.clip(pos - jb, 0.0, 1.0)
            fr = frs
        out.append((j0, fr))
    return out


def _delay_columns_at(S: Samples, items: list) -> list:
    """:func:`delay_column` of every (shift, beta) of items, in one pass over each log: the samples the ends
    interpolate between marked for all of them, what the torque model reads there gathered once
    (:func:`_torque_features`), each item's model and ends from it. The ends of a sample are its index plus
    a whole offset and a fraction common to all samples (:func:`_ends`): the folds' shifts are close, so the
    positions of the few distinct offsets among the marked samples are looked up once for all items."""
    outs = [np.empty(S.n) for _ in items]
    for i, lg in enumerate(S.logs):
        sel = S.li == i
        if not sel.any():
            continue
        k = S.k[sel].astype(np.int64)
        ends = [_ends(S, i, k, shift_s, lg.n) for shift_s, _ in items]
        # the torque model once at each sample the two ends interpolate between (they overlap: the
        # sliding samples come in runs, and the shifts of the folds are close), then read at both ends
        mark = np.zeros(lg.n, bool)
        for e in ends:
            for j0, _ in e:
                mark[j0] = True
                mark[j0 + 1] = True
        idx = np.flatnonzero(mark)
        del mark
        feats = _torque_features(S, i, idx)
        at = np.empty(lg.n, np.int64)   # the position of each marked sample in idx (only those are read)
        at[idx] = np.arange(idx.size)
        pos: dict = {}   # the positions in idx of j0 and j0 + 1, by the ends' arrays (shared by offset)

        def where(j0):
            if id(j0) not in pos:   # the arrays live in ``ends`` while pos does
                pos[id(j0)] = (at[j0], at[j0 + 1])
            return pos[id(j0)]

        by_offset: dict = {}   # ends with the same whole offset and no clipped sample share their positions
        for e in ends:
            for n, (j0, fr) in enumerate(e):
                if np.ndim(fr) == 0:
                    off = int(j0[0] - k[0])
                    e[n] = (by_offset.setdefault(off, j0), fr)
        for (shift_s, beta), out, e in zip(items, outs, ends):
            T = _torque_model(feats, beta)
            val = []
            for j0, fr in e:
                p0, p1 = where(j0)
                a, b = T[p0], T[p1]
                a *= 1 - fr
                b *= fr
                a += b
                val.append(a)
            val[0] -= val[1]
            val[0] /= shift_s
            out[sel] = val[0]
    return outs


def _fold_delay_terms(S: Samples) -> list:
    """The (shift, map) of each training set's delay term (:func:`delay_estimates`, :func:`delay_map`), as
    :func:`frictid.diagnose.causes.propose` makes them (cached)."""
    def compute():
        nf = S.n_folds
        return [(float(d), delay_map(S, d, [g for g in range(nf) if g != f]))
                for f, d in enumerate(delay_estimates(S))]
    return S.cached("delay_fold_terms", compute)


def share_delay_terms(S: Samples, sub: Samples) -> None:
    """Give ``sub``, a stride of S's samples (:mod:`frictid.diagnose.search`), S's training sets' delay terms
    once S has estimated them (:func:`delay_estimates`, :func:`_fold_delay_terms`): a screen's delay terms
    are the whole logs' (:meth:`frictid.diagnose.chain.Chain._propose`), and with them :func:`delay_column`
    on the stride forms the five training sets' columns in one pass (:func:`_delay_columns_at`), not one
    pass per column, each over the whole logs' length. A sample's value does not depend on the other
    samples of the pass: the same columns."""
    if S.has("delay_estimates") and not sub.has("delay_fold_terms"):
        sub.cached("delay_estimates", lambda: delay_estimates(S))
        sub.cached("delay_fold_terms", lambda: _fold_delay_terms(S))


def delay_column(S: Samples, shift_s: float, beta: tuple = ()) -> np.ndarray:
    """At the sliding samples: ``(T(t + shift/2) - T(t - shift/2)) / shift`` [F/s] with ``T`` the torque the
    motion explains (:func:`_torque_model`, the map fitted with the delay): the rate of the torque over the
    delay, centred (its coefficient is the delay [s]; ``tau(t) - tau(t - shift)`` is what a delay leaves, to
    first order). Not the measured torque's own rate: the friction torque it is fitted to carries the
    torque sensor's noise, and a difference of measured torques would explain part of that noise and pass
    for a delay on a clean log (or, centred, be attenuated by it). The Savitzky-Golay rate of the measured
    torque when the shift is zero.

    The training sets' columns (:func:`_fold_delay_terms`) are computed together when one of them is asked
    for (:func:`_delay_columns_at`): the folds' proposals ask for each in turn."""
    if shift_s == 0:
        return torque_rate(S)
    key = _column_key(shift_s, beta)
    if S.has(key):
        return S.cached(key, lambda: None)
    items = [(shift_s, beta)]
    if S.has("delay_estimates"):
        folds = [x for x in _fold_delay_terms(S) if x[0] != 0 and not S.has(_column_key(*x))]
        if any(_column_key(*x) == key for x in folds):
            items = folds
    for x, col in zip(items, _delay_columns_at(S, items)):
        S.cached(_column_key(*x), lambda c=col: c)
    return S.cached(key, lambda: None)


def _moving_groups(S: Samples, every: bool = False) -> list:
    """Per log: the held-out group of each moving sample of :func:`_moving_rows` (``every`` as there; that of
    the nearest sliding sample in time, as its fold is; cached)."""
    def compute():
        out = []
        for i, (km, _) in enumerate(_moving_rows(S, every)):
            if not km.size:
                out.append(np.zeros(0, np.int64))
                continue
            out.append(_labels_at(S, i, S.group, km, ("moving_nearest", every, i)))
            S.forget(("moving_nearest", every, i))   # the folds and groups both formed
        return out
    if every and (S.bristle is None or not S.bristle > 0):
        return _moving_groups(S)
    return S.cached("moving_groups_every" if every else "moving_groups", compute)


def delay_heldout(S: Samples, shifts: list) -> tuple[float, float, np.ndarray]:
    """The delay judged where it shows, on every moving sample (transients included, where the torque
    changes fastest): per fold ``f`` the velocity-only map with inertia and gravity corrections
    (:func:`_delay_columns`) fitted on the other folds with the torque shifted by ``shifts[f]`` and without
    a shift, both predicting the held-out fold's friction torque. The shift is rounded to whole samples
    here: a torque interpolated between two samples averages their noise, and a fraction of a sample would
    "explain" up to 30 % of the sensor's noise on a clean log (the delay search's own sub-sample shifts
    of clean logs, 0.3-0.6 sample periods, are mostly that). Returns the RMS of the held-out residuals
    without and with the shift and, per held-out group (that of the nearest sliding sample), the sum of
    ``r_before^2 - r_after^2``."""
    return _judged(S, None, [float(x) for x in shifts], whole=True)


def delay_mirror(S: Samples, shifts: list, centre: float) -> tuple[float, float, np.ndarray]:
    """A shift of a fraction of a sample judged against its mirror image about ``centre`` [s] (the
    velocity's own lag, :func:`frictid.diagnose.chain.velocity_lag`), on every moving sample as
    :func:`delay_heldout` judges whole shifts: per fold the delay's map fitted on the other folds with the
    torque shifted by the fold's shift and by ``2 centre - shift``, both interpolated (not rounded), both
    predicting the held-out fold. The two interpolations average the torque sensor's noise alike (their
    weights are the same two numbers, swapped), and so low-pass the torque alike: what the noise's
    averaging gains, each gains, and only a torque late (or early) against the motion prefers one side.
    Returns the held-out RMS with the mirror and with the shift and, per held-out group, the sum of
    ``r_mirror^2 - r_shift^2``: against no delay at all a shift explains about a quarter of that."""
    return _judged(S, [2.0 * centre - float(x) for x in shifts], [float(x) for x in shifts], whole=False)


def _judged(S: Samples, before: list | None, after: list, whole: bool) -> tuple[float, float, np.ndarray]:
    """Per fold the delay's map fitted on the other folds with the torque shifted by the fold's shift of
    ``before`` (None: no shift) and of ``after`` [s], each predicting the held-out fold on every moving
    sample; shifts rounded to whole samples where ``whole``, else interpolated. Returns the held-out RMS
    before and after and, per held-out group, the sum of ``r_before^2 - r_after^2``
    (:func:`delay_heldout`, :func:`delay_mirror`)."""
    nf = S.n_folds
    _delay_prefetch(S, ([0.0] if before is None else before) + after)
    fits = []
    for f in range(nf):
        train = [g for g in range(nf) if g != f]
        fits.append((_delay_fit(S, 0.0 if before is None else before[f], train, rss=False)[0],
                     _delay_fit(S, after[f], train, rss=False)[0]))
    if any(b0 is None or b1 is None for b0, b1 in fits):
        return math.nan, math.nan, np.zeros(S.n_groups)
    d = np.zeros(S.n_groups)
    ss0 = ss1 = 0.0
    n = 0
    B0 = np.array([b for b, _ in fits])
    B1 = np.array([b for _, b in fits])
    for i, ((km, fk), gk) in enumerate(zip(_moving_rows(S, True), _moving_groups(S, True))):
        lg = S.logs[i]
        tau = finite(lg.tau)
        s0 = None if before is None else np.asarray(before, float) / S.dt(i)
        s1 = np.asarray(after, float) / S.dt(i)
        for b in range(0, km.size, BLOCK):
            k, f, g = km[b:b + BLOCK], fk[b:b + BLOCK], gk[b:b + BLOCK]
            X = _delay_columns(S, i, k)
            base = lg.F[k] - tau[k]
            r0 = (lg.F[k] if s0 is None else base + shifted_torque(tau, k.astype(float), s0[f])) \
                - np.einsum("ij,ij->i", X, B0[f])
            sh = np.round(s1[f]) if whole else s1[f]   # whole samples: no interpolation
            r1 = base + shifted_torque(tau, k.astype(float), sh) - np.einsum("ij,ij->i", X, B1[f])
            d += np.bincount(g, weights=r0 * r0 - r1 * r1, minlength=S.n_groups)
            ss0 += float(r0 @ r0)
            ss1 += float(r1 @ r1)
            n += k.size
    return math.sqrt(ss0 / max(n, 1)), math.sqrt(ss1 / max(n, 1)), d


def moving_samples(S: Samples) -> int:
    """The number of moving samples :func:`delay_estimate` fits."""
    return int(sum(km.size for km, _ in _moving_rows(S)))


def delay_limit(S: Samples) -> float:
    """The longest delay [s] searched: :data:`DELAY_MAX_RUN` of the mean run of one sign (at least a sample)."""
    return max(DELAY_MAX_RUN * _run_time(S), S.dt(0))
