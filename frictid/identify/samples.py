"""Static maps identified on all moving samples, for logs whose plateaus cannot carry them.

Excitation trajectories (multi-sine, back-and-forth moves, a robot's identification run) have no
constant-velocity plateaus, and a trajectory with plateaus at only two or three speeds per sign (the EMPS
benchmark) gives too few distinct points for a Stribeck or polynomial map. Such logs are identified as the
inverse-dynamics identification model (IDIM-LS, 002 eq 4-11; the EMPS reference) does it, on every moving
sample::

    tau = J a + G(q) + offset + F(w)

J, the gravity terms and the offset come from the linear stage (:mod:`.regression`, with the polynomial
friction, linear in all its parameters). Each static map is then fitted to the friction samples
``F = tau - J a - G(q) - offset`` by the same bounded least squares (variable projection) as on plateau points
(:func:`.static.fit_static`): linear maps (``coulomb_viscous``, ``polynomial`` and their ``_asym``
variants) have a unique optimum; the Stribeck maps get the same scan of their shape parameters.

Held out by time blocks, never by sample: the moving samples of all logs, laid end to end in time, are cut
into ``BLOCKS_PER_FOLD * n_folds`` blocks of equal duration and block ``k`` goes to fold ``k mod n_folds``
(every fold spans the whole recording). Consecutive samples are strongly correlated (filtered derivatives,
the controller): the covariance is inflated by the variance factor of the linear stage's residuals
(batch means, :func:`variance_factor`) and the information criterion counts the effective number of
independent samples, ``n`` divided by that factor.

Which basis a joint uses (:func:`choose_basis`): the plateaus when they give at least
:data:`MIN_PLATEAU_LEVELS` distinct speeds on each velocity sign they cover, else the moving samples.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from frictid.result import ModelFit
from frictid.models import static as sm

from .static import _IMPACT_POWER, NEGLIGIBLE, _aic, fit_static, predict, warm_start

#: Distinct plateau speeds per velocity sign needed to fit the static maps on plateau points.
MIN_PLATEAU_LEVELS = 5
#: Two plateau speeds are distinct when they differ by more than this fraction of the larger one.
LEVEL_TOLERANCE = 0.1
#: Time blocks per fold of the held-out split.
BLOCKS_PER_FOLD = 4
#: Most samples kept per joint (evenly strided beyond this).
MAX_SAMPLES = 2_000_000
#: Velocity bins per sign of the least squares, and the fewest samples in a bin.
BINS_PER_SIGN = 200
MIN_PER_BIN = 5
#: Fewest moving samples for the sample basis.
MIN_SAMPLES = 50


def speed_levels(w: np.ndarray, tol: float = LEVEL_TOLERANCE) -> int:
    """Number of distinct speeds among plateau speeds ``w`` [q/s] of one sign (relative tolerance ``tol``)."""
    v = np.sort(np.abs(np.asarray(w, dtype=float)))
    if v.size == 0:
        return 0
    n, ref = 1, v[0]
    for x in v[1:]:
        if x - ref > tol * x:
            n += 1
            ref = x
    return n


def choose_basis(plateau_w: np.ndarray, n_moving: int) -> tuple[str, str]:
    """``("plateaus" | "samples", why)`` for a joint with plateau speeds ``plateau_w`` and ``n_moving``
    moving samples."""
    pos = speed_levels(plateau_w[plateau_w > 0])
    neg = speed_levels(plateau_w[plateau_w < 0])
    enough = [lv >= MIN_PLATEAU_LEVELS for lv in (pos, neg) if lv > 0]
    if enough and all(enough):
        return "plateaus", f"plateaus at {pos} distinct positive and {neg} negative speeds"
    if n_moving < MIN_SAMPLES:
        return "plateaus", f"only {n_moving} moving samples"
    what = ("no constant-velocity plateaus" if pos + neg == 0 else
            f"plateaus at only {pos} distinct positive and {neg} negative speeds (at least "
            f"{MIN_PLATEAU_LEVELS} per sign needed)")
    return "samples", f"{what}: the static maps are fitted on the {n_moving} moving samples"


@dataclass
class SampleSet:
    """Friction samples of one joint for the sample basis.

    w [q/s], F [F] (``tau - J a - G - offset``), block : time-block index, fold : ``block % n_folds``,
    log : index of the prepared log each sample came from, stride : subsampling step (1 = every sample),
    n_moving : moving samples before subsampling, inflation : variance inflation of autocorrelated
    samples (:func:`variance_factor` of the linear stage's residuals).
    """

    w: np.ndarray
    F: np.ndarray
    block: np.ndarray
    fold: np.ndarray
    log: np.ndarray
    stride: int
    n_moving: int
    n_folds: int
    inflation: float = 1.0
    #: what the samples were taken from (:func:`build`): per log its velocity array and the mask of the
    #: samples kept, and the stride; two sets with the same source hold the same samples (:meth:`share_order`)
    source: tuple | None = None

    @property
    def n(self) -> int:
        return int(self.w.shape[0])

    @property
    def n_eff(self) -> float:
        """Effective number of independent samples."""
        return self.n / self.inflation

    def by_speed(self) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]:
        """Per velocity sign (positive, then negative): ``(w, F, fold)`` of its samples in increasing |w|
        (stable), computed once: every binning of these samples or of a subset of folds
        (:func:`_bin_samples`) takes them from here instead of sorting and gathering again."""
        out = self.__dict__.get("_by_speed")
        if out is None:
            out = tuple((self.w[idx], self.F[idx], self.fold[idx]) for idx in self.speed_order())
            self.__dict__["_by_speed"] = out
        return out

    def sorted_velocity_folds(self) -> tuple[tuple[np.ndarray, np.ndarray], ...] | None:
        """Per velocity sign, the velocity and folds of :meth:`by_speed` (what another set of the same samples
        shares, :meth:`share_sorted`), or None when they have not been sorted."""
        out = self.__dict__.get("_by_speed")
        return None if out is None else tuple((w, f) for w, _, f in out)

    def share_sorted(self, wf: tuple[tuple[np.ndarray, np.ndarray], ...], bins: dict | None = None) -> None:
        """Take :meth:`by_speed` from another set of the same samples (its :meth:`sorted_velocity_folds`, after
        :meth:`share_order` took its speed order): only this set's friction is gathered in that order; and its
        :meth:`velocity_bins` (``bins``, that set's :meth:`velocity_bins_cache`) when given."""
        self.__dict__["_by_speed"] = tuple((w, self.F[idx], f) for (w, f), idx in zip(wf, self.speed_order()))
        self.__dict__["_velocity_bins"] = {} if bins is None else bins

    def velocity_bins_cache(self) -> dict:
        """What :meth:`velocity_bins` holds (another set of the same samples takes it, :meth:`share_sorted`)."""
        return self.__dict__.setdefault("_velocity_bins", {})

    def velocity_bins(self, leave_out: int | None, per_sign: int) -> list:
        """Per velocity sign, the velocity side of :func:`_bin_samples` (the samples outside fold ``leave_out``,
        all when None; ``per_sign`` equal-count bins): ``(mask of the kept samples in the order of
        :meth:`by_speed` or None, the bins' first indices among them, counts, mean velocities)``, all None for
        a sign without kept samples. Cached: it depends on the velocity and the folds only, so every map fitted
        on these samples, and another set of the same samples, bins only its friction."""
        cache = self.velocity_bins_cache()
        key = (leave_out, per_sign)
        if key not in cache:
            out = []
            for ww, _, fold in self.by_speed():
                keep = None if leave_out is None else fold != leave_out
                wk = ww if keep is None else ww[keep]
                if not wk.size:
                    out.append((None, None, None, None))
                    continue
                edges, cnt = _bin_edges(wk.size, per_sign)
                out.append((keep, edges, cnt, np.add.reduceat(wk, edges) / cnt))
            cache[key] = out
        return cache[key]

    def speed_order(self) -> tuple[np.ndarray, np.ndarray]:
        """Indices of the positive, then the negative velocity samples in increasing |w| (stable), sorted
        once (or taken from a set with the same samples, :meth:`share_order`)."""
        order = self.__dict__.get("_speed_order")
        if order is None:
            order = []
            for idx in (np.flatnonzero(self.w > 0), np.flatnonzero(self.w < 0)):
                order.append(idx[argsort_stable(np.abs(self.w[idx]))])
            order = self.__dict__["_speed_order"] = tuple(order)
        return order

    def order_key(self) -> "SpeedOrder | None":
        """This set's :meth:`speed_order` with what identifies its samples, to hand to another set of the
        same samples (:meth:`share_order`) without keeping this one (None without a known source)."""
        return None if self.source is None else SpeedOrder(self.source, self.n_folds, self.speed_order())

    def share_order(self, key: "SpeedOrder | None") -> bool:
        """Take the speed order of ``key`` (:meth:`order_key` of another set) when both sets hold the same
        samples: taken from the same velocity arrays with the same masks, stride and folds (the friction
        may differ: two models' targets on one joint's samples). True when taken."""
        if key is None or self.source is None or key.n_folds != self.n_folds:
            return False
        (w1, m1, st1), (w2, m2, st2) = key.source, self.source
        if st1 != st2 or len(w1) != len(w2) or any(a is not b for a, b in zip(w1, w2)):
            return False
        if any(a.shape != b.shape or not np.array_equal(a, b) for a, b in zip(m1, m2)):
            return False
        self.__dict__["_speed_order"] = key.order
        self.__dict__.pop("_by_speed", None)
        self.__dict__.pop("_velocity_bins", None)
        return True


@dataclass
class SpeedOrder:
    """A sample set's speed order and the source of its samples (:meth:`SampleSet.order_key`): the masks
    and the order are about a tenth of the set's memory."""

    source: tuple
    n_folds: int
    order: tuple


def argsort_stable(a: np.ndarray) -> np.ndarray:
    """``np.argsort(a, kind="stable")`` of a float array, by a faster unstable sort whose runs of equal
    values (NaNs together) are then put back in index order."""
    a = np.asarray(a, dtype=float)
    order = np.argsort(a)
    s = a[order]
    same = (s[1:] == s[:-1]) | (np.isnan(s[1:]) & np.isnan(s[:-1]))
    if same.any():  # sort by (rank of the distinct value, index): unique int64 keys
        rank = np.concatenate([[0], np.cumsum(~same)])
        order = order[np.argsort(rank * a.size + order)]
    return order


def block_ranges(t_list: list[np.ndarray], n_folds: int) -> list[list[tuple[int, int, int]]]:
    """Per log, ``(i0, i1, block)`` index ranges of the time blocks (logs laid end to end in time).

    Sample ``i`` of a log is in block ``min((t_i - t_0 + t_off) // L, n_blocks - 1)``. The times of a log
    increase, so the blocks are found at their edges: a bisection of t per edge, settled on that formula
    evaluated at the samples beside the edge (no pass over every sample)."""
    spans = [float(t[-1] - t[0]) if t.size > 1 else 0.0 for t in t_list]
    total = sum(spans)
    n_blocks = BLOCKS_PER_FOLD * n_folds
    L = total / n_blocks if total > 0 else 1.0
    out, t_off = [], 0.0
    for t, span in zip(t_list, spans):
        if t.size == 0:
            out.append([])
            continue

        def block(i, t=t, t_off=t_off):
            return min(int(((t[i:i + 1] - t[0] + t_off) // L)[0]), n_blocks - 1)

        n = t.size
        rr, i0 = [], 0
        for k in range(block(0) + 1, block(n - 1) + 1):
            i = int(np.searchsorted(t, t[0] - t_off + k * L))  # first sample of block k, to rounding
            i = min(max(i, i0), n - 1)
            while i > i0 and block(i - 1) >= k:
                i -= 1
            while i < n and block(i) < k:
                i += 1
            if i > i0:
                rr.append((i0, i, block(i0)))
                i0 = i
        rr.append((i0, n, block(i0)))
        out.append(rr)
        t_off += span
    return out


def build(logs, min_speed: float, n_folds: int, exclude: tuple[str, ...] = (),
          max_samples: int = MAX_SAMPLES) -> SampleSet | None:
    """The moving friction samples of a joint's prepared logs (each with ``.log``, ``.w``, ``.F`` and
    ``.segments``): |w| > min_speed, finite, outside segments of the kinds in ``exclude``."""
    ranges = block_ranges([np.asarray(p.log.t, float) for p in logs], n_folds)
    ws, Fs, bs, ls = [], [], [], []
    src_w, src_m = [], []
    for li, (p, rr) in enumerate(zip(logs, ranges)):
        if p.F is None:
            continue
        m = np.isfinite(p.w) & np.isfinite(p.F) & (np.abs(p.w) > min_speed)
        for s in p.segments:
            if s.kind in exclude:
                m[s.i0:s.i1] = False
        src_w.append(p.w)
        src_m.append(m)
        ws.append(p.w[m])
        Fs.append(p.F[m])
        # the kept samples' blocks: the ranges cover the log in order, so each block's value repeated for
        # its kept samples (no block array over every sample of the log: fresh pages, issue 20)
        bs.append(np.repeat(np.array([b for _, _, b in rr], dtype=np.int64),
                            [np.count_nonzero(m[i0:i1]) for i0, i1, _ in rr]))
        ls.append(np.full(int(m.sum()), li))
    if not ws:
        return None
    # one log's arrays are its own gathers already: no copy of them (fresh pages, issue 20)
    w, F, blk, lg = (x[0] if len(x) == 1 else np.concatenate(x) for x in (ws, Fs, bs, ls))
    n_moving = int(w.shape[0])
    if n_moving < MIN_SAMPLES:
        return None
    stride = max(1, math.ceil(n_moving / max_samples))
    if stride > 1:
        sl = slice(0, None, stride)
        w, F, blk, lg = w[sl], F[sl], blk[sl], lg[sl]
    return SampleSet(w, F, blk, blk % n_folds, lg, stride, n_moving, n_folds,
                     source=(tuple(src_w), tuple(src_m), stride))


def variance_factor(r: np.ndarray) -> float:
    """Variance inflation of the mean of autocorrelated residuals ``r`` (in time order), by batch means:
    ``m var(batch means) / var(r)`` with batches of ``m = sqrt(n)`` consecutive samples (1 for white
    noise; ``(1 + rho) / (1 - rho)`` for a first-order autoregression). At least 1."""
    r = np.asarray(r, dtype=float)
    n = r.size
    v = float(np.var(r))
    m = int(math.sqrt(n))
    if m < 2 or v <= 0:
        return 1.0
    k = n // m
    bm = r[:k * m].reshape(k, m).mean(axis=1)
    return max(1.0, m * float(np.var(bm)) / v)


def bin_points(w: np.ndarray, F: np.ndarray, per_sign: int = BINS_PER_SIGN
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Means of (w, F) in velocity bins of equal counts, per sign: (w_bin [q/s], F_bin [F], count).

    The samples of each sign in their stable order by |w| (zero and NaN velocities left out) are cut into
    ``min(per_sign, n // MIN_PER_BIN)`` bins of equal counts. The definition, for any arrays; a
    :class:`SampleSet` is binned by :func:`_bin_samples`, which gives the same bins from its sorted copy."""
    order = np.argsort(np.abs(w), kind="stable")
    ws = w[order]
    return _join_bins([_sign_bins(ws[m], F[order[m]], per_sign)
                       for m in (np.sign(ws) == 1.0, np.sign(ws) == -1.0) if m.any()])


def _sign_bins(ww: np.ndarray, ff: np.ndarray, per_sign: int):
    """Equal-count bin means of one sign's samples (w, F) already in increasing |w|, and the counts."""
    edges, cnt = _bin_edges(ww.size, per_sign)
    return np.add.reduceat(ww, edges) / cnt, np.add.reduceat(ff, edges) / cnt, cnt


def _bin_edges(n: int, per_sign: int) -> tuple[np.ndarray, np.ndarray]:
    """The first index and the count of each of the equal-count bins of ``n`` samples of one sign."""
    nb = max(1, min(per_sign, n // MIN_PER_BIN))
    edges = np.linspace(0, n, nb + 1).astype(np.int64)[:-1]
    return edges, np.diff(np.append(edges, n))


def _join_bins(parts):
    """One (w_bin, F_bin, count) from the per-sign ones (counts as floats)."""
    if not parts:
        z = np.zeros(0)
        return z, z, z
    wb, Fb, cnt = (np.concatenate(x) for x in zip(*parts))
    return wb, Fb, cnt.astype(float)


def _bin_samples(S: SampleSet, leave_out: int | None = None, per_sign: int = BINS_PER_SIGN):
    """:func:`bin_points` of the samples of S outside fold ``leave_out`` (all when None), from the
    speed-sorted samples of :meth:`SampleSet.by_speed` (the same bins, without sorting again) and their
    velocity side from :meth:`SampleSet.velocity_bins` (the same numbers: only the friction is summed here)."""
    parts = []
    for (keep, edges, cnt, wm), (_, ff, _) in zip(S.velocity_bins(leave_out, per_sign), S.by_speed()):
        if edges is not None:
            parts.append((wm, np.add.reduceat(ff if keep is None else ff[keep], edges) / cnt, cnt))
    return _join_bins(parts)


def _fit_binned(name, bins, axis, start=None, var_inflation=1.0, profile=None) -> ModelFit:
    wb, Fb, nb = bins
    return fit_static(name, wb, Fb, 1.0 / np.sqrt(nb), axis=axis, start=start, var_inflation=var_inflation,
                      profile=profile)


def fit_map(name: str, S: SampleSet, axis: str = "rotary", heldout: bool = True, errors: bool = True) -> ModelFit:
    """Static map ``name`` (symmetric or ``_asym``) on the friction samples, with held-out error by fold
    (:func:`heldout_map`; ``heldout=False``: None, for the caller to compute when needed), standard errors
    of autocorrelated samples and AIC on the effective sample count. ``errors=False``: the held-out refits'
    jackknife is not taken into the standard errors (:func:`heldout_map`), for a caller that reads the
    held-out error alone (the diagnosis' check).

    The least squares runs on velocity-bin means weighted by their counts (:func:`bin_points`; the same
    objective as on the samples while the map is smooth across a bin, and hundreds of times faster);
    its covariance is then rescaled to the residual variance of the samples times their variance factor.
    """
    bins = wb, Fb, nb = _bin_samples(S)
    mf = _fit_binned(name, bins, axis)
    vals = mf.values()
    k = int(mf.metrics.get("k") or 0)
    r = predict(name, vals, S.w) - S.F
    ok = np.isfinite(r)
    n = int(ok.sum())
    rss = float(np.sum(r[ok] ** 2))
    del r, ok  # two arrays of the samples' length fewer through the held-out refits (the check's peak)
    held = None
    if all(v is not None for v in vals.values()):
        # covariance of the samples: residual variance of the samples, inflated for their autocorrelation,
        # instead of the scatter of the bin means (a second pass from the optimum, one start)
        rb = predict(name, vals, wb) - Fb
        s2_bins = float(np.sum(nb * rb**2)) / max(wb.size - k, 1)
        s2_samples = rss / max(n - k, 1)
        if s2_bins > 0:
            first = mf.notes  # why the first pass held what the second holds again (e.g. delta at 2)
            mf = _fit_binned(name, bins, axis, start=warm_start(mf),
                             var_inflation=S.inflation * s2_samples / s2_bins, profile=True)
            mf.notes = first + [nt for nt in mf.notes if nt not in first]
            vals = mf.values()
        if heldout:
            held = heldout_map(name, S, mf, axis, errors)
    mf.metrics = sample_metrics(rss, n, k, held, S)
    mf.method = ("bounded least squares on the moving samples (velocity-bin means), F = tau - J a - G(q) - "
                 "offset with J, gravity and offset from the linear stage"
                 + ("" if mf.map.startswith(("coulomb", "polynomial")) else ", variable projection"))
    mf.extra["basis"] = "moving samples"
    return mf


def heldout_map(name: str, S: SampleSet, mf: ModelFit, axis: str = "rotary", errors: bool = True) -> float | None:
    """Held-out RMS [F] of map ``name`` on the samples: refitted without each fold (warm-started at the
    fit ``mf`` on all samples), predicting the fold. None when a prediction is not finite. With ``errors``
    the fold refits (and a refit without each recording) raise ``mf``'s standard errors
    (:func:`jackknife_errors`, :func:`recording_errors`); they do not change the held-out RMS."""
    if any(v is None for v in mf.values().values()):
        return None
    start = warm_start(mf)
    ph = np.full(S.n, np.nan)
    refits = []
    for f in range(S.n_folds):
        te = S.fold == f
        if not te.any() or te.all():
            continue
        m = _fit_binned(name, _bin_samples(S, leave_out=f), axis, start=start)
        refits.append(m.values())
        ph[te] = predict(name, m.values(), S.w[te])
    if errors:
        jackknife_errors(mf, refits, S)
        recording_errors(mf, name, S, axis, start)
    ph -= S.F  # the held-out residual, in place
    if np.isfinite(ph).all():
        return float(math.sqrt(np.mean(np.square(ph, out=ph))))
    return None


def jackknife_errors(mf: ModelFit, refits: list[dict], S: SampleSet) -> None:
    """Standard errors no smaller than the delete-a-fold jackknife over the time-block folds
    (``sqrt((G-1)/G sum (p_g - mean)^2)`` over the G refits without one fold each): the spread of the
    parameters from one stretch of the log to another, which the variance factor of the samples misses
    when the misfit drifts along the log (a friction that changes with position or temperature, the
    rigid-body terms' error). A parameter whose error so grows above 100 % of its value, with a torque
    effect that is not negligible (the rule of the static fits), becomes not identifiable. Per parameter,
    the jackknife error is recorded in ``mf.extra["jackknife_stderr"]``."""
    if len(refits) < 3:
        return
    _raise_to_jackknife(mf, refits, S, "jackknife over the time-block folds")


def jackknife_se(fits) -> np.ndarray:
    """Delete-a-group jackknife standard errors of estimates over ``k`` groups (rows of ``fits``: each the
    estimate without one group): ``sqrt((k - 1) / k * sum((x - mean)^2))`` per column."""
    B = np.asarray(fits, dtype=float)
    k = B.shape[0]
    return np.sqrt((k - 1) / k * np.sum((B - B.mean(0)) ** 2, axis=0))


def _raise_to_jackknife(mf: ModelFit, refits: list[dict], S: SampleSet, what: str) -> None:
    """Standard errors raised to the delete-a-group jackknife of ``refits`` where it is larger, and the
    parameters whose error so exceeds 100 % (with a torque effect that is not negligible) not identifiable."""
    dims = {p.name: p.dim for p in sm.param_table(mf.map)}
    F0 = float(np.percentile(np.abs(S.F), 99.5)) if S.n else 0.0
    w0 = float(np.percentile(np.abs(S.w), 99.5)) if S.n else 0.0
    for n, pe in mf.params.items():
        vals = np.array([r.get(n) for r in refits], dtype=float)
        if pe.fixed or pe.value is None or pe.stderr is None or not np.all(np.isfinite(vals)):
            continue
        se_j = float(jackknife_se(vals))
        if se_j <= pe.stderr:
            continue
        pe.stderr = se_j
        powr = _IMPACT_POWER.get(dims.get(n, ""))
        impact = None if powr is None else se_j * w0**powr
        if pe.identifiable and se_j > abs(pe.value) and (impact is None or impact > NEGLIGIBLE * F0):
            pe.identifiable = False
            pe.reason = (f"relative error {100 * se_j / abs(pe.value):.0f} % (above 100 %; {what})"
                         if pe.value else "relative error above 100 %")


def _bins_without_log(S: SampleSet, g: int, per_sign: int = BINS_PER_SIGN):
    """:func:`bin_points` of the samples of S that are not from log ``g``."""
    parts = []
    for idx in S.speed_order():
        idx = idx[S.log[idx] != g]
        if idx.size:
            parts.append(_sign_bins(S.w[idx], S.F[idx], per_sign))
    return _join_bins(parts)


def recording_errors(mf: ModelFit, name: str, S: SampleSet, axis: str, start: dict) -> None:
    """With samples from several recordings (logs) of the joint, standard errors no smaller than the
    delete-a-recording jackknife (``sqrt((G-1)/G sum (p_g - mean)^2)`` over the G refits without one
    recording each; with two, half the difference between the two recordings' maps): what changes from one
    recording to another (the day, the temperature, the drive's state, the excitation) is an error of the
    joint's friction that no sample of one recording shows (issue 19: on the UR10e the standard errors were
    10-20 times smaller than the difference between two recordings of one joint). The time-block folds
    mix the recordings and miss it. The rule of :func:`jackknife_errors` then applies."""
    logs = np.unique(S.log)
    if logs.size < 2:
        return
    refits = []
    for g in logs:
        bins = _bins_without_log(S, int(g))
        if bins[0].size == 0:
            return
        refits.append(_fit_binned(name, bins, axis, start=start).values())
    _raise_to_jackknife(mf, refits, S, "jackknife over the recordings")


def sample_metrics(rss: float, n: int, k: int, rms_heldout: float | None, S: SampleSet) -> dict:
    """rms, rms_heldout, aic (on the effective sample count), n, n_eff and k of a fit on samples."""
    n_eff = n / S.inflation
    aic = None
    if n > 0 and rss > 0:
        aic = _aic(rss / n * n_eff, max(int(round(n_eff)), 1), k)
    return {"rms": math.sqrt(rss / n) if n else None, "rms_heldout": rms_heldout, "aic": aic, "n": int(n),
            "n_eff": float(n_eff), "k": int(k)}


#: Maps whose Coulomb level and viscous slope are read as the friction's (the line, and the Stribeck map's
#: steady part): on the moving samples they carry their change to the faster half (:func:`speed_split_spread`).
LEVEL_SLOPE_MAPS = ("coulomb_viscous", "coulomb_viscous_asym", "stribeck", "stribeck_asym")


def _faster_half(wb: np.ndarray, nb: np.ndarray) -> np.ndarray | None:
    """The bins of each sign above that sign's median sample speed (by the bins' counts); None when a
    sign has fewer than four bins above it."""
    fast = np.zeros(wb.size, bool)
    for sgn in (1.0, -1.0):
        idx = np.flatnonzero(np.sign(wb) == sgn)
        if idx.size == 0:
            continue
        idx = idx[np.argsort(np.abs(wb[idx]), kind="stable")]
        cum = np.cumsum(nb[idx])
        upper = idx[cum > 0.5 * cum[-1]]
        if upper.size < 4:
            return None
        fast[upper] = True
    return fast if fast.any() else None


def speed_split_spread(mf: ModelFit, name: str, S: SampleSet, axis: str = "rotary") -> None:
    """The map refitted on the faster half of the moving samples (per sign, above its median speed); the
    change of each branch's ``Fc`` and ``sigma2`` enters their standard errors (added in quadrature), as the
    inertia's speed split does for J. A friction that is a line in the speed, or a Stribeck map that
    follows it, gives the same level and slope on both; a drop the map does not follow (on point-to-point
    moves the speeds below the cruises are crossed only while accelerating, where the friction lags, so
    the Stribeck map sees no drop) bends the line through the slower samples: on the foreign scorecard's
    point-to-point excitations Fc came out 3-35 % high and sigma2 30-90 % low with errors of a few tenths
    of a percent. Recorded per parameter in ``mf.extra["speed_split"]``."""
    if name not in LEVEL_SLOPE_MAPS:
        return
    vals = mf.values()
    if any(v is None for v in vals.values()):
        return
    wb, Fb, nb = _bin_samples(S)
    fast = _faster_half(wb, nb)
    if fast is None:
        return
    try:
        alt = _fit_binned(name, (wb[fast], Fb[fast], nb[fast]), axis, start=warm_start(mf)).values()
    except (np.linalg.LinAlgError, FloatingPointError, ValueError):
        return
    rec = {}
    dims = {p.name: p.dim for p in sm.param_table(mf.map)}
    F0 = float(np.percentile(np.abs(S.F), 99.5)) if S.n else 0.0
    w0 = float(np.percentile(np.abs(S.w), 99.5)) if S.n else 0.0
    for n, pe in mf.params.items():
        if n.split("_")[0] not in ("Fc", "sigma2") or pe.value is None or pe.stderr is None:
            continue
        a = alt.get(n)
        if a is None or not np.isfinite(a):
            continue
        rec[n] = float(a)
        pe.stderr = float(np.hypot(pe.stderr, a - pe.value))
        powr = _IMPACT_POWER.get(dims.get(n, ""))
        impact = None if powr is None else pe.stderr * w0**powr
        if pe.identifiable and pe.stderr > abs(pe.value) and (impact is None or impact > NEGLIGIBLE * F0):
            pe.identifiable = False
            pe.reason = (f"relative error {100 * pe.stderr / abs(pe.value):.0f} % (above 100 %): "
                         f"{a:.4g} on the faster half of the moving samples: the friction is not "
                         "this map's over the speeds")
    mf.extra["speed_split"] = rec
