"""Static friction maps from constant-velocity plateaus (MODELS.md section 2, 001 eq 8-9, 000 eq 11).

Each constant-velocity segment gives one averaged point ``(w, F)`` with its standard error
(:func:`plateau_points`). The maps are fitted to these points by bounded nonlinear least squares
(:func:`fit_static`) whose bounds, start and scale come from the parameter tables of
:mod:`frictid.models.static` scaled to the data. The maps are separable: for each value of their shape
parameters (the Stribeck velocities and exponent) the linear ones are solved exactly, and the optimiser works
on the shape parameters alone (variable projection, :mod:`.varpro`), after a scan of the reduced cost over a
grid of shape values where the problem is not convex.

Standard errors come from the Jacobian at the optimum, ``cov = s^2 (J^T J)^-1`` with ``s^2`` the
reduced chi-square (the plateau standard errors weight the points, the scatter sets the scale). Each plateau
is one segment, so this already is the segment-to-segment scatter; a sandwich (HC1/HC3) estimate was
tried and not kept: on 14 plateaus per branch it put the near-collinear amplitudes of stribeck_2exp_asym
above 100 % relative error and the choice fell back to a map with 2.4x the curve error. The Stribeck
drop's parameters, read from the few slowest plateaus, have an error no smaller than the delete-a-pair
jackknife over the points (:func:`_pair_jackknife`: a pair of plateaus at one speed shares its bias).
A parameter is marked ``identifiable: false`` with the reason when it sits at a bound, when its relative
error exceeds 100 % and matters at the data scale, when the Jacobian is rank-deficient along it, or when
there are no data for it (a per-sign branch without plateaus).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from frictid.models import static as sm
from frictid.models.params import Param, scaled_table, unit_of

from . import varpro as vp

from frictid.result import ModelFit, ParamEstimate

#: Power of the velocity scale by which a parameter of this dimension multiplies into a torque.
_IMPACT_POWER = {"F": 0, "D": 1, "D2": 2, "D3": 3}

#: Evaluations of the reduced residual per shape parameter (plus one) allowed to one refinement
#: (degenerate valleys of the two-exponential map otherwise run for thousands of steps without changing
#: the curve).
MAX_NFEV_PER_PARAM = 40
#: ... of which each valley of a cold scan gets this many before the best one is run to the end.
SCREEN_NFEV_PER_PARAM = 8

#: Relative size (of the torque scale) below which an uncertain parameter does not matter.
NEGLIGIBLE = 0.01

#: Shape parameters of each map and the amplitude they shape, as a contrast of linear parameters
#: (name -> coefficient). A decay speed or exponent means something only when its amplitude does.
SHAPES = {"stribeck": ((("vs", "delta"), {"Fs": 1.0, "Fc": -1.0}, "the Stribeck drop Fs - Fc"),),
          "stribeck_2exp": ((("ws1",), {"alpha1": 1.0}, "the Stribeck amplitude alpha1"),
                            (("ws2",), {"alpha2": 1.0}, "the second amplitude alpha2"))}
#: Prefix of a warm start's key that holds a parameter at the given value (:func:`warm_start`).
HELD = "__held_"
#: Standard errors an amplitude must stand clear of zero for its shape parameters to be identifiable.
SHAPE_Z = 2.0
#: The reason's words for a parameter along the Jacobian's null space.
RANK_DEFICIENT = "Jacobian rank-deficient"


@dataclass
class Plateaus:
    """Averaged steady-state points, one per constant-velocity segment.

    w [q/s], F [F]: plateau means; F_se, w_se: their standard errors (batch means, robust to the
    autocorrelation of samples; a plateau whose friction still settles gives its later half,
    :func:`_settled_mean`); n: samples used; t_start, t_end [s]; seg: index into the segment list.
    """

    w: np.ndarray
    F: np.ndarray
    F_se: np.ndarray
    w_se: np.ndarray
    n: np.ndarray
    t_start: np.ndarray
    t_end: np.ndarray
    seg: np.ndarray

    def __len__(self) -> int:
        return int(self.w.shape[0])

    def subset(self, mask) -> "Plateaus":
        mask = np.asarray(mask)
        return Plateaus(*(getattr(self, f)[mask] for f in
                          ("w", "F", "F_se", "w_se", "n", "t_start", "t_end", "seg")))


def _batch_se(x: np.ndarray, n_batches: int) -> float:
    """Standard error of the mean of x from the spread of ``n_batches`` batch means."""
    n = x.shape[0]
    if n < 2:
        return math.nan
    nb = max(2, min(n_batches, n // 2 if n >= 4 else n))
    edges = np.linspace(0, n, nb + 1).astype(int)
    means = np.add.reduceat(x, edges[:-1]) / np.diff(edges)
    return float(np.std(means, ddof=1) / math.sqrt(nb))


def _settled_mean(x: np.ndarray, n_batches: int) -> tuple[float, float]:
    """A plateau's friction as an estimate of its *steady* level, and its standard error: the mean with
    its batch-means error (:func:`_batch_se`, which assumes the friction is stationary along the plateau),
    unless the friction is still settling. After a speed change the bristles (or the loop) approach their
    steady state, exponentially with some time constant tau; inside a plateau of duration T that biases the
    whole mean against the level it settles at by about ``A tau / T``, and half the difference ``d`` of the
    means of the plateau's later and earlier halves measures the same bias (on a stationary plateau it is
    noise of the size of the batch-means error). Beyond :data:`SETTLING_Z` of that error (a drift, not
    noise: stationary plateaus keep their mean and error, so the points' weights do not take on the
    halves' noise) and slowing down (:data:`SETTLING_DECAY`), the point is the later half's mean, nearer the settled level, with the error
    ``max(|d|, its batch-means error)``: what the later half may still carry of the settling is at most
    what the halves differ by. Foreign card: a sweep's slowest plateaus (0.01 rad/s, 0.75 s) settled for a
    third of their length; the whole mean sat 3.7 of its batch-means errors (0.94 N m) below the steady
    friction and pulled Fs 1.6 % low, trusted; the later half is 0.31 N m below, within its error 0.63."""
    m, se, _ = _settled(x, n_batches)
    return m, se


def _settled(x: np.ndarray, n_batches: int) -> tuple[float, float, int]:
    """:func:`_settled_mean`'s mean and error, and the first sample of ``x`` it averaged (0, or the later
    half's first when the friction is still settling)."""
    m, se = float(x.mean()), _batch_se(x, n_batches)
    h = x.shape[0] // 2
    if h < 4 or not math.isfinite(se):
        return m, se, 0
    late = float(x[h:].mean())
    d = 0.5 * (late - float(x[:h].mean()))
    q = [float(c.mean()) for c in np.array_split(x, 4)]
    early_change, late_change = q[1] - q[0], q[3] - q[2]
    decays = early_change * late_change >= 0.0 and abs(late_change) < SETTLING_DECAY * abs(early_change)
    if abs(d) <= SETTLING_Z * se or not decays:
        return m, se, 0
    return late, max(abs(d), _batch_se(x[h:], n_batches)), h


#: A plateau's friction counts as still settling when half the difference of its halves' means exceeds
#: SETTLING_Z batch-means errors and the change slows down: the last quarter's change (against the third)
#: is below SETTLING_DECAY of the first's (the second against the first), with the same sign
#: (:func:`_settled_mean`). A drift that does not slow down (a torque that depends on the position the
#: plateau travels through, a thermal drift) is not settling: the whole mean is the plateau's level at its
#: mean position, and the later half would move it by half the drift.
SETTLING_Z = 2.0
SETTLING_DECAY = 0.5


def plateau_points(t, w, F, segments, trim: float = 0.1, n_batches: int = 10,
                   min_speed: float = 0.0) -> Plateaus:
    """One averaged ``(w, F)`` point per constant-velocity segment.

    t [s], w [q/s], F [F] : per-sample time, velocity and friction torque (``tau - J a - G - offset``).
    segments : :class:`frictid.data.Segment` list (only ``constant_velocity`` ones are used).
    trim : fraction cut from each end of a plateau (transients). Plateaus whose velocity changes sign or
    whose mean speed is below ``min_speed`` are skipped.
    """
    rows = [(float(ww.mean()), m, se, _batch_se(ww, n_batches), ww.shape[0], float(t[s.i0]), float(t[s.i1 - 1]), k)
            for k, s, ww, _, m, se in _plateau_windows(w, F, segments, trim, n_batches, min_speed)]
    if not rows:
        z = np.zeros(0)
        return Plateaus(z, z, z, z, z.astype(int), z, z, z.astype(int))
    a = list(zip(*rows))
    return Plateaus(np.array(a[0]), np.array(a[1]), np.array(a[2]), np.array(a[3]),
                    np.array(a[4], dtype=int), np.array(a[5]), np.array(a[6]), np.array(a[7], dtype=int))


def plateau_column_means(w, F, segments, cols, trim: float = 0.1, n_batches: int = 10,
                         min_speed: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Per plateau of :func:`plateau_points` (same arguments), the means of each of ``cols`` (per-sample
    arrays) over the very samples its friction point averaged: the plateau's trimmed finite samples, or
    their later half where the friction was still settling. A column that changes along a plateau (the
    gravity torque of a joint moving through its angles) averaged over other samples than the friction
    would not say how an error of its coefficient moves the point. Returns the plateaus' segment indices
    (``Plateaus.seg``) and the means, shape (plateaus, columns)."""
    seg, out = [], []
    for k, _, _, (idx, h), _, _ in _plateau_windows(w, F, segments, trim, n_batches, min_speed):
        seg.append(k)
        out.append([float(np.asarray(c, dtype=float)[idx][h:].mean()) for c in cols])
    return np.array(seg, dtype=int), np.array(out, dtype=float).reshape(len(out), len(cols))


def _plateau_windows(w, F, segments, trim: float, n_batches: int, min_speed: float):
    """Per usable constant-velocity segment ``k``: (k, segment, its speeds, (sample indices, first of them
    averaged), the friction point's mean and error) (:func:`plateau_points`)."""
    for k, s in enumerate(segments):
        if s.kind != "constant_velocity":
            continue
        m = s.i1 - s.i0
        cut = int(trim * m)
        i0, i1 = s.i0 + cut, s.i1 - cut
        if i1 - i0 < 4:
            continue
        ww = np.asarray(w[i0:i1], dtype=float)
        ff = np.asarray(F[i0:i1], dtype=float)
        ok = np.isfinite(ww) & np.isfinite(ff)
        ww, ff = ww[ok], ff[ok]
        if ww.shape[0] < 4:
            continue
        wm = float(ww.mean())
        if abs(wm) <= min_speed or np.mean(np.sign(ww) == np.sign(wm)) < 0.95:
            continue
        mean, se, h = _settled(ff, n_batches)
        yield k, s, ww, (i0 + np.flatnonzero(ok), h), mean, se


# ---------------------------------------------------------------------------------------------------
# The bounded nonlinear fit of one branch


@dataclass
class BranchFit:
    """Fit of one symmetric map on one set of points (internal)."""

    values: dict
    stderr: dict
    reasons: dict
    fixed: dict
    cov: np.ndarray | None
    free: list
    cost: float
    success: bool
    message: str
    #: a rise that fits the points as well as this drop (name -> value), or None (:meth:`_Branch._drop_first`)
    rival: dict | None = None


def _scales(w, F):
    F0 = float(np.max(np.abs(F))) if len(F) else 1.0
    w0 = float(np.max(np.abs(w))) if len(w) else 1.0
    return (F0 if F0 > 0 else 1.0), (w0 if w0 > 0 else 1.0)


def _weights(F_se, F0, n):
    if F_se is None:
        return np.ones(n)
    se = np.asarray(F_se, dtype=float).copy()
    good = np.isfinite(se) & (se > 0)
    if not good.any():
        return np.ones(n)
    floor = max(0.5 * float(np.median(se[good])), 1e-9 * F0)
    se[~good] = floor
    return 1.0 / np.maximum(se, floor)


@dataclass
class _Branch:
    """The least-squares problem of one symmetric map on one set of points: the free parameters (indices
    into ``names``), their bounds and scales, the point weights and the data scales F0 [F], w0 [q/s]."""

    smap: sm.StaticMap
    names: list[str]
    fixed: dict
    free: list[int]
    w: np.ndarray
    F: np.ndarray
    wts: np.ndarray
    lo_f: np.ndarray
    hi_f: np.ndarray
    xs_f: np.ndarray
    F0: float
    w0: float

    def full(self, xf):
        x = np.array([self.fixed.get(nm, 0.0) for nm in self.names], dtype=float)
        x[self.free] = xf
        return x

    def resid(self, xf):
        x = self.full(xf)
        return (self.smap.func(self.w, **dict(zip(self.names, x))) - self.F) * self.wts

    def jac(self, xf):
        x = self.full(xf)
        return self.smap.jac(self.w, **dict(zip(self.names, x)))[:, self.free] * self.wts[:, None]

    def search(self, tries: list[dict], cold: bool):
        """The least-squares solution (:class:`.varpro.Solution`) by variable projection, or None.

        The linear parameters are solved exactly for each value of the shape parameters (:data:`frictid.models.static.SEPARABLE`).
        A cold fit scans the reduced cost over a grid of shape values and the starts ``tries`` (name ->
        value), refines the best point of each of its lowest valleys briefly (:data:`SCREEN_NFEV_PER_PARAM`)
        and runs the best of them on to convergence; a warm start
        (``cold`` False: a held-out refit from the full-data optimum, the only entry of ``tries``) is
        refined from where it is, to convergence: stopped early,
        the refit would stay near an optimum that saw the held-out points (a budget of 10 per parameter cut
        stribeck_2exp_asym's held-out error by 2.6x on the direct drive: leakage, not skill)."""
        if self.w.shape[0] == 0 or not tries:
            return None
        pr = vp.Projection(self)
        shape = [self.names[self.free[j]] for j in pr.nl]
        budget = MAX_NFEV_PER_PARAM * (len(shape) + 1)
        try:
            with np.errstate(all="ignore"):
                if shape and cold:
                    grid = vp.shape_grid(shape, self.w, self.lo_f[pr.nl], self.hi_f[pr.nl], tries)
                    starts = pr.scan(grid, vp.N_VALLEYS[self.smap.name])
                else:
                    starts = [np.array([tries[0][nm] for nm in shape], dtype=float)]
                screen = SCREEN_NFEV_PER_PARAM * (len(shape) + 1) if len(starts) > 1 else budget
                tried = [pr.refine(t, screen) for t in starts]
                run_on = lambda r: (pr.refine(r.x[pr.nl], budget - screen)  # noqa: E731
                                    if r.status == 0 and screen < budget else r)  # stopped by the screening budget
                res = self._drop_first(run_on(min(tried, key=lambda r: r.cost)), tried, run_on)
                res = self._ordered(pr, res)
        except (ValueError, np.linalg.LinAlgError):  # e.g. non-finite residuals from a degenerate start
            return None
        return res if np.all(np.isfinite(res.fun)) else None

    def _rises(self, res) -> bool:
        """A Stribeck solution whose break-away level is below its Coulomb level (a rise, not a drop)."""
        x = dict(zip(self.names, self.full(res.x)))
        return self.smap.name == "stribeck" and x["Fs"] < x["Fc"]

    def _drop_first(self, res, tried: list, run_on):
        """A Stribeck fit (:func:`frictid.models.static.stribeck` is 003's drop, Fs >= Fc) that a cold
        search ends in a rise, when a drop among the valleys ``tried`` fits as well (within
        :data:`DELTA_CHI2` of chi-square, scaled by the rise's reduced chi-square): the drop, with the rise
        as its ``rival`` (the data cannot tell them apart, and the map's definition decides:
        :func:`_fit_one_branch` notes the rise, :func:`_rival_note`). A rise that fits clearly better stays (issue 19: it is named, and the choice
        takes a map that follows it). The search is free to find either: which valley of two the data
        cannot tell apart it ends in says nothing about the data, and the map's definition does."""
        if not self._rises(res):
            return res
        drops = [r for r in tried if not self._rises(r)]
        if not drops:
            return res
        drop = run_on(min(drops, key=lambda r: r.cost))
        dof = max(self.w.shape[0] - len(self.free), 1)
        s2 = 2.0 * res.cost / dof
        if self._rises(drop) or not (s2 > 0 and 2.0 * (drop.cost - res.cost) / s2 <= DELTA_CHI2):
            return res
        drop.rival = dict(zip(self.names, (float(v) for v in self.full(res.x))))
        return drop

    def _ordered(self, pr, res):
        """A two-exponential fit with its speeds in order, ws1 <= ws2: the mirror image of an optimum with
        them the other way round is the same curve (:func:`frictid.models.static.stribeck_2exp_swapped`),
        and which of the two a search ends in says nothing about the data."""
        if self.smap.name != "stribeck_2exp" or self.fixed:
            return res
        x = dict(zip(self.names, self.full(res.x)))
        if x["ws1"] <= x["ws2"]:
            return res
        sw = sm.stribeck_2exp_swapped(**x)
        xf = np.array([sw[self.names[k]] for k in self.free])
        if np.any(xf < self.lo_f) or np.any(xf > self.hi_f):
            return res
        return pr.solution(xf, res.status, res.message)


def fit_branch(base: str, w, F, F_se=None, fixed: dict | None = None,
               scales: tuple[float, float] | None = None, start: dict | None = None,
               var_inflation: float = 1.0) -> BranchFit:
    """Fit symmetric map ``base`` to points (w [q/s], F [F]) by bounded, weighted least squares.

    fixed : parameters held at given values. scales : (F0, w0) data scales for the bounds (default:
    the largest |F| and |w| of the points). start : a warm start (name -> value); then it is the only
    start (used by the held-out refits, which begin at the full-data optimum). var_inflation : factor on
    the covariance before the identifiability checks (1 for plateau points; :mod:`.samples` uses it to
    turn the covariance of binned points into that of autocorrelated samples).
    """
    smap = sm.STATIC_MAPS[base]
    table: tuple[Param, ...] = smap.table
    names = [p.name for p in table]
    fixed = dict(fixed or {})
    w = np.asarray(w, dtype=float)
    F = np.asarray(F, dtype=float)
    n = w.shape[0]
    F0, w0 = scales if scales else _scales(w, F)
    lo, hi, x0_tab, xs = scaled_table(table, F0, w0)
    free = [k for k, nm in enumerate(names) if nm not in fixed]
    pb = _Branch(smap, names, fixed, free, w, F, _weights(F_se, F0, n), lo[free], hi[free], xs[free], F0, w0)
    cold = not (start is not None and all(start.get(nm) is not None for nm in names))
    best = pb.search([dict(zip(names, x0_tab)) if cold else start], cold)  # the table's start joins the scan
    if best is None:
        vals = {nm: None for nm in names}
        vals.update(fixed)
        why = "no data" if n == 0 else "optimiser failed"
        return BranchFit(vals, {nm: None for nm in names}, {nm: why for nm in names if nm not in fixed},
                         fixed, None, [names[k] for k in free], math.nan, False, why)
    x = pb.full(best.x)
    stderr, reasons, cov = _branch_errors(pb, best, var_inflation)
    _bound_and_error_reasons(pb, best, x, table, stderr, reasons)
    return BranchFit(dict(zip(names, (float(v) for v in x))), stderr, reasons, fixed, cov,
                     [names[k] for k in free], float(best.cost), bool(best.success), str(best.message), best.rival)


def _branch_errors(pb: _Branch, best, var_inflation: float) -> tuple[dict, dict, np.ndarray | None]:
    """Standard errors of the free parameters from the Jacobian at the optimum (``cov = s^2 (J^T J)^-1``,
    times ``var_inflation``), the parameters along the Jacobian's null space with their reason, and the
    covariance (None without residual degrees of freedom)."""
    names, free, xs_f = pb.names, pb.free, pb.xs_f
    stderr: dict = {nm: None for nm in names}
    reasons: dict = {}
    n, p = pb.w.shape[0], len(free)
    dof = n - p
    if dof <= 0:
        for k in free:
            reasons[names[k]] = (f"{n} points for {p} free parameters: no residual left to estimate "
                                 "the error")
        return stderr, reasons, None
    Jm = best.jac
    s2 = 2.0 * best.cost / dof
    Js = Jm * xs_f[None, :]
    U, sv, Vt = np.linalg.svd(Js, full_matrices=False)
    tol = sv.max() * 1e-9 if sv.size and sv.max() > 0 else 1.0
    ok = sv > tol
    inv = (Vt[ok].T / sv[ok] ** 2) @ Vt[ok]
    cov = s2 * float(var_inflation) * inv * np.outer(xs_f, xs_f)
    null = Vt[~ok]
    for j, k in enumerate(free):
        nm = names[k]
        se = math.sqrt(max(cov[j, j], 0.0))
        stderr[nm] = se
        if null.size and np.max(np.abs(null[:, j])) > 0.1:
            reasons[nm] = f"not separable from other parameters ({RANK_DEFICIENT})"
    return stderr, reasons, cov


def _bound_and_error_reasons(pb: _Branch, best, x: np.ndarray, table, stderr: dict, reasons: dict) -> None:
    """Add the reason of each free parameter at a bound, or whose relative error is above 100 % and whose
    effect on the torque is not negligible."""
    lo_f, hi_f = pb.lo_f, pb.hi_f
    for j, k in enumerate(pb.free):
        nm = pb.names[k]
        if nm in reasons:
            continue
        span = hi_f[j] - lo_f[j]
        if best.active_mask[j] != 0 or x[k] - lo_f[j] < 1e-6 * span or hi_f[j] - x[k] < 1e-6 * span:
            side = "lower" if x[k] - lo_f[j] < hi_f[j] - x[k] else "upper"
            reasons[nm] = f"at its {side} bound ({lo_f[j] if side == 'lower' else hi_f[j]:.4g})"
            continue
        se = stderr[nm]
        if se is not None and (x[k] == 0 or se > abs(x[k])):
            dim = table[k].dim
            powr = _IMPACT_POWER.get(dim)
            impact = None if powr is None else se * pb.w0**powr
            if impact is None or impact > NEGLIGIBLE * pb.F0:
                rel = se / abs(x[k]) if x[k] != 0 else math.inf
                reasons[nm] = f"relative error {100 * rel:.0f} % (above 100 %)"


def warm_start(full: ModelFit) -> dict:
    """Start of a refit (a held-out fold) at the optimum of ``full``, with the parameters it held (delta at
    2, the shape of a drop it could not see) held at the same values and with the same verdict: key
    ``HELD + name``, value ``(value, reason it is not identifiable or "")``."""
    start = full.values()
    start.update({HELD + k: (p.value, "" if p.identifiable else p.reason) for k, p in full.params.items()
                  if p.fixed and p.value is not None})
    return start


def _shapeless(base: str, values: dict, cov: np.ndarray, free: list[str], reasons: dict | None = None
               ) -> dict[str, str]:
    """Shape parameters (decay speeds, exponent) of map ``base`` whose amplitude is within
    :data:`SHAPE_Z` standard errors of zero, or not separable from the other parameters (``reasons``: the
    Jacobian rank-deficient along it, e.g. two exponentials at one speed with amplitudes that cancel), with
    the reason: a drop that the data cannot tell from none has no speed at which it decays (one plateau
    speed, or a map without a Stribeck effect)."""
    out = {}
    for shape, contrast, what in SHAPES.get(base, ()):
        tied = [nm for nm in contrast if RANK_DEFICIENT in (reasons or {}).get(nm, "")]
        for nm in shape if tied else ():
            if nm in free:
                out[nm] = (f"{what} is not separable from the other parameters ({tied[0]}: Jacobian rank-deficient): "
                           "the speed and shape of its drop cannot be placed; held where the fit put it")
    shapes = SHAPES.get(base, ())
    precision = np.linalg.pinv(cov) if shapes else None
    for shape, contrast, what in shapes:
        # the amplitude's error with its shape held where it is: a drop whose speed trades with the other
        # terms still counts when, at that speed, it stands clear of zero
        keep = [j for j, nm in enumerate(free) if nm not in shape]
        cond = np.linalg.pinv(precision[np.ix_(keep, keep)])
        c = np.array([contrast.get(free[j], 0.0) for j in keep])
        amp = sum(coef * values[nm] for nm, coef in contrast.items())
        se = math.sqrt(max(float(c @ cond @ c), 0.0))
        if abs(amp) < SHAPE_Z * se:
            for nm in shape:
                if nm in free and nm not in out:
                    out[nm] = (f"{what} = {amp:.3g} +- {se:.2g} is not distinguishable from zero: the speed "
                               "and shape of a drop the data do not show cannot be placed; held where the fit put it")
    return out


# ---------------------------------------------------------------------------------------------------
# Public entry: symmetric or per-sign map on plateau points


def _aic(rss: float, n: int, k: int) -> float | None:
    """Akaike information criterion with the small-sample correction (AICc) for Gaussian residuals."""
    if n <= 0 or rss <= 0:
        return None
    aic = n * math.log(rss / n) + 2 * k
    if n - k - 1 > 0:
        aic += 2 * k * (k + 1) / (n - k - 1)
    else:
        return None
    return aic


def _block_diag(mats: list) -> np.ndarray:
    """``scipy.linalg.block_diag(*mats)`` of 2-d arrays (the same array), without its argument handling
    (a third of a millisecond a call, once for every map of every fit)."""
    shape = np.sum([m.shape for m in mats], axis=0)
    out = np.zeros(shape, dtype=np.result_type(*[m.dtype for m in mats]))
    r = c = 0
    for m in mats:
        out[r:r + m.shape[0], c:c + m.shape[1]] = m
        r, c = r + m.shape[0], c + m.shape[1]
    return out


def metrics(name: str, values: dict, w, F, k: int) -> dict:
    """rms [F], n, k and aic of a static map's values on points (w, F)."""
    pred = predict(name, values, w)
    r = pred - F
    ok = np.isfinite(r)
    n = int(ok.sum())
    rss = float(np.sum(r[ok] ** 2))
    return {"rms": math.sqrt(rss / n) if n else None, "n": n, "k": int(k), "aic": _aic(rss, n, k)}


def predict(name: str, values: dict, w, formula: bool = False) -> np.ndarray:
    """Friction [F] of static map ``name`` (symmetric or ``_asym``) at w, as a parameter file runs it (a
    negative level held at zero; ``formula``: as written, :func:`frictid.models.static.evaluate`); NaN where a
    branch is unknown."""
    w = np.asarray(w, dtype=float)
    smap, asym = sm.split_asym(name)
    if not asym:
        if any(values.get(n) is None for n in smap.names):
            return np.full(w.shape, np.nan)
        return sm.evaluate(name, w, values, formula)
    out = np.full(w.shape, np.nan)
    for suf, m in (("_pos", w >= 0), ("_neg", w < 0)):
        vals = {n: values.get(n + suf) for n in smap.names}
        if any(v is None for v in vals.values()):
            continue
        out[m] = sm.evaluate(smap.name, w[m], vals, formula)
    return out


def fit_static(name: str, w, F, F_se=None, axis: str = "rotary", delta: str | float = "auto",
               fixed: dict | None = None, start: dict | None = None, var_inflation: float = 1.0,
               shifts=None, profile: bool | None = None, jackknife: bool = False) -> ModelFit:
    """Fit static map ``name`` (``stribeck``, ``polynomial_asym``, ...) to plateau points.

    w [q/s], F [F], F_se [F] : plateau means and standard errors. axis : "rotary" or "linear" (units).
    delta : Stribeck exponent, "auto" (free when the data pin it, else fixed at 2 as in 000/003), "free",
    or a number to hold it at. fixed : other parameters to hold (name -> value, suffixed for _asym).
    var_inflation : covariance factor for autocorrelated points (see :func:`fit_branch`).
    shifts : the points' changes [F] for one standard deviation of each independent error direction of
    what was subtracted from the torque (:func:`_shift_profile`), or None.
    profile : run the exponent's profiles (:func:`_delta_profile`, :func:`_free_delta_profile`); default on
    a cold fit only (a held-out refit from the full fit's optimum does not use its errors). A second pass
    whose errors are reported (:func:`.samples.fit_map`'s, warm-started) asks for them: without, the moving
    samples' fits lost the held exponent's spread (foreign 204552: delta held at 2, truth 1.53, Fs 13 % low
    at 9 errors and vs 85 % off at 8, trusted).
    jackknife : the drop's errors no smaller than the delete-a-pair jackknife over the plateau points
    (:func:`_pair_jackknife`; plateau points only, on a profiled fit).
    A per-sign model is fitted branch by branch (the branches share no parameter).
    """
    w = np.asarray(w, dtype=float)
    F = np.asarray(F, dtype=float)
    F_se = None if F_se is None else np.asarray(F_se, dtype=float)
    smap, asym = sm.split_asym(name)
    fixed = dict(fixed or {})
    F0, w0 = _scales(w, F)
    notes: list[str] = []
    shifts = [np.asarray(d, dtype=float) for d in (shifts or ())]
    if not asym:
        branches = [("", w, F, F_se, "")]
        bshifts = {"": shifts}
    else:
        pos, neg = w > 0, w < 0
        branches = [("_pos", w[pos], F[pos], None if F_se is None else F_se[pos], "positive"),
                    ("_neg", -w[neg], -F[neg], None if F_se is None else F_se[neg], "negative")]
        bshifts = {"_pos": [d[pos] for d in shifts], "_neg": [-d[neg] for d in shifts]}
    params: dict[str, ParamEstimate] = {}
    covs = []
    k_total = 0
    success = True
    for suf, bw, bF, bse, side in branches:
        bfixed = {n: fixed[n + suf] for n in smap.names if n + suf in fixed}
        bfixed = _held_delta(smap.name, bfixed, delta, bw.shape[0], suf, notes)
        p_free = len(smap.names) - len(bfixed)
        n = bw.shape[0]
        if n < p_free:
            what = f"{side}-velocity plateaus" if side else "plateaus"
            why = f"no {what}" if n == 0 else f"only {n} {what} for {p_free} parameters"
            params.update(_missing_branch(smap, suf, bfixed, why, axis))
            success = False
            continue
        bf, shapeless = _fit_one_branch(smap.name, bw, bF, bse, bfixed, suf, start, delta, (F0, w0),
                                        var_inflation, notes, bshifts[suf],
                                        start is None if profile is None else profile, jackknife)
        success = success and bf.success
        k_total += len(bf.free)
        if bf.cov is not None:
            covs.append(bf.cov)
        params.update(_branch_params(smap, suf, bf, shapeless, axis, (F0, w0)))
        _drop_in_view(smap.name, bw, params, suf)
    values = {k: v.value for k, v in params.items()}
    met = metrics(name, values, w, F, k_total)
    cov = _block_diag(covs) if covs else None
    mf = ModelFit(name=name, map=name, params=params, metrics=met, notes=notes, success=success, cov=cov,
                  method="bounded nonlinear least squares on plateau points, variable projection"
                  if not smap.linear else "bounded least squares on plateau points")
    return mf


#: A Stribeck drop's level at zero speed (break-away) counts as measured when the slowest point still
#: holds this share of the drop (a quarter of the drop seen; below, the standard error of an extrapolation
#: assumes the map's shape holds where no point is); its end level when the fastest point holds less than
#: DROP_ENDED (the drop half over by the top speed).
DROP_SEEN = 0.25
DROP_ENDED = 0.5


def _drop_in_view(base: str, bw: np.ndarray, params: dict, suf: str) -> None:
    """A drop the branch's speeds do not see is extrapolated, not measured: when the slowest point holds
    less than :data:`DROP_SEEN` of the fitted drop, the break-away level and the drop's speed and shape are
    not identifiable (the drop lies below the data: a sweep whose slow plateaus were lost); when the
    fastest holds more, the level it drops to and the speed are not (the drop has not ended by the top
    speed). The Jacobian's rank does not show it: with a few points on the drop's tail the amplitude and
    its speed trade off within 100 % errors."""
    v = np.abs(np.asarray(bw, float))
    v = v[np.isfinite(v) & (v > 0)]
    if v.size == 0:
        return
    g = lambda n: params.get(n + suf)  # noqa: E731
    if base == "stribeck":
        vs, dl = g("vs"), g("delta")
        if vs is None or dl is None or not vs.value or vs.value <= 0 or dl.value is None:
            return
        share = lambda x: math.exp(-((x / vs.value) ** dl.value))  # noqa: E731
        low, high = ("Fs", "vs", "delta"), ("Fc", "vs", "delta")
    elif base == "stribeck_2exp":
        ws1 = g("ws1")
        if ws1 is None or not ws1.value or ws1.value <= 0:
            return
        share = lambda x: math.exp(-x / ws1.value)  # noqa: E731
        low, high = ("alpha1", "ws1"), ()
    else:
        return
    s_lo, s_hi = share(float(v.min())), share(float(v.max()))
    if s_lo < DROP_SEEN:
        why = (f"the slowest point ({v.min():.3g}) holds {100 * s_lo:.0f} % of the fitted drop: the break-away "
               "level and the drop's speed are extrapolated below the data")
        names = low
    elif s_hi > DROP_ENDED:
        why = (f"the fastest point ({v.max():.3g}) still holds {100 * s_hi:.0f} % of the fitted drop: the level "
               "it drops to and its speed are extrapolated above the data")
        names = high
    else:
        return
    for n in names:
        pe = g(n)
        if pe is not None and pe.identifiable and not pe.fixed:
            pe.identifiable, pe.reason = False, why


def _held_delta(base: str, bfixed: dict, delta, n: int, suf: str, notes: list[str]) -> dict:
    """A branch's held parameters with the Stribeck exponent held as ``delta`` asks: at a given number, or
    at 2 (000/003) when "auto" and the branch has too few plateaus to free it (noted in ``notes``)."""
    p_free = len(sm.STATIC_MAPS[base].names) - len(bfixed)
    if base == "stribeck" and "delta" not in bfixed and delta != "free" and delta != "auto":
        bfixed["delta"] = float(delta)
    if base == "stribeck" and delta == "auto" and "delta" not in bfixed and n <= p_free:
        bfixed["delta"] = 2.0
        notes.append(f"delta{suf} fixed at 2 (000/003): {n} plateaus are too few to free it")
    return bfixed


def _missing_branch(smap, suf: str, bfixed: dict, why: str, axis: str) -> dict[str, ParamEstimate]:
    """The parameters of a branch with too few points: none identifiable, held ones at their value."""
    params = {}
    for prm in smap.table:
        unit = unit_of(prm.dim, axis)
        if prm.name in bfixed:
            params[prm.name + suf] = ParamEstimate(prm.name + suf, bfixed[prm.name], None, unit,
                                                   False, why, fixed=True)
        else:
            params[prm.name + suf] = ParamEstimate(prm.name + suf, None, None, unit, False, why)
    return params


def _fit_one_branch(base: str, bw, bF, bse, bfixed: dict, suf: str, start: dict | None, delta, scales,
                    var_inflation: float, notes: list[str], shifts=None, profile: bool = True,
                    jackknife: bool = False) -> tuple[BranchFit, dict[str, str]]:
    """Fit one branch: from the warm start (its held parameters held again), then with the shape of a drop
    the data cannot tell from none held where it came out, then (delta "auto") with a Stribeck exponent
    the data do not pin held at 2 (:func:`_pinned_delta`). Returns the fit and the held shapes' reasons (suffixed names)."""
    shapeless: dict[str, str] = {}
    bstart = None
    if start is not None:
        bstart = {n: start.get(n + suf) for n in sm.STATIC_MAPS[base].names}
        for n in sm.STATIC_MAPS[base].names:
            if (h := start.get(HELD + n + suf)) is not None:
                bfixed[n] = h[0]
                if h[1]:
                    shapeless[n + suf] = h[1]
    bf = fit_branch(base, bw, bF, bse, bfixed, scales=scales, start=bstart, var_inflation=var_inflation)
    held = {} if bf.cov is None else _shapeless(base, bf.values, bf.cov, bf.free, bf.reasons)
    if held:  # a drop the data cannot tell from none: its shape held where it came out, the rest refitted
        bfixed.update({nm: bf.values[nm] for nm in held})
        bf = fit_branch(base, bw, bF, bse, bfixed, scales=scales, start=bstart, var_inflation=var_inflation)
        shapeless.update({nm + suf: why for nm, why in held.items()})
    if base == "stribeck" and delta == "auto" and "delta" not in bfixed:
        bf = _pinned_delta(bw, bF, bse, bfixed, suf, bstart, scales, var_inflation, notes, bf)
    if bf.rival:  # a rise fits as well: the drop stands, its levels and slope carry the difference
        _rival_spread(bf, bf.rival)
        notes.append(_rival_note(bf.rival, suf))
    if base == "stribeck" and delta == "auto" and profile and bf.cov is not None:
        if "delta" in bfixed:
            _delta_profile(bw, bF, bse, bfixed, scales, var_inflation, bf)
        else:
            _free_delta_profile(bw, bF, bse, bfixed, scales, var_inflation, bf)
    if base == "stribeck" and jackknife and profile and bf.cov is not None:
        _pair_jackknife(bw, bF, bse, bfixed, scales, var_inflation, bf)
    if shifts and bf.cov is not None:
        _shift_profile(base, bw, bF, bse, bfixed, scales, var_inflation, bf, shifts)
    if base == "stribeck" and bf.cov is not None and _degenerate_drop(bf, bfixed, shapeless, suf, scales):
        _shape_profile(bw, bF, bse, bfixed, scales, var_inflation, bf)
    return bf, shapeless


def _pinned_delta(bw, bF, bse, bfixed: dict, suf: str, start: dict | None, scales, var_inflation: float,
                  notes: list[str], bf: BranchFit) -> BranchFit:
    """A free Stribeck exponent (delta "auto") that the data do not pin down held at 2 (000/003), the branch
    refitted: one not identifiable by its own error, or, on a cold fit, one whose profile reaches a bound of
    its table: the fit with delta held at that bound (from the free optimum, as :func:`_delta_profile` refits
    at each exponent around a held one) is within :data:`DELTA_CHI2` of chi-square of the free fit (the
    profile's "fits as well"), so no interval of exponents the data support closes. The linearised error misses it: at a step-like drop
    between two plateau speeds the chi-square is flat from 1.5 to the bound 5 while the Jacobian gives
    3.8 +- 2.2. ``bfixed`` is changed in place; returns the fit to keep."""
    if "delta" in bf.reasons:
        why = f"free, it was not identifiable ({bf.reasons['delta']})"
    elif start is not None or bf.cov is None:  # a warm refit keeps the full fit's verdict (:func:`warm_start`)
        return bf
    else:
        s2 = 2.0 * bf.cost / max(len(bw) - len(bf.free), 1)
        prm = next(p for p in sm.STATIC_MAPS["stribeck"].table if p.name == "delta")
        open_at = None
        for d in (prm.upper, prm.lower) if s2 > 0 else ():
            alt = fit_branch("stribeck", bw, bF, bse, dict(bfixed, delta=d), scales=scales,
                             start=dict(bf.values, delta=d), var_inflation=var_inflation)
            if math.isfinite(alt.cost) and 2.0 * (alt.cost - bf.cost) / s2 <= DELTA_CHI2:
                open_at = d
                break
        if open_at is None:
            return bf
        why = (f"the data do not pin it (free at {bf.values['delta']:.3g}, and at its bound {open_at:g} the fit "
               f"is within {DELTA_CHI2:g} of chi-square)")
    bfixed["delta"] = 2.0
    notes.append(f"delta{suf} fixed at 2 (000/003): {why}")
    return fit_branch("stribeck", bw, bF, bse, bfixed, scales=scales, start=start, var_inflation=var_inflation)


def _rival_note(r: dict, suf: str) -> str:
    """The note on a Stribeck drop that a rise ``r`` (:meth:`_Branch._drop_first`) fits as well as (see
    :func:`_rival_spread`)."""
    return (f"branch{suf or ' (symmetric)'}: a rise (Fs {r['Fs']:.4g} below Fc {r['Fc']:.4g}, vs {r['vs']:.3g}, "
            f"delta {r['delta']:.3g}) fits the points within {DELTA_CHI2:g} of chi-square of this drop")


#: The parameters a Stribeck drop and a rise share as physical quantities: the levels at zero and at high
#: speed and the viscous slope (a drop's speed is where it stops falling, a rise's where it stops rising).
SHARED_WITH_A_RISE = ("Fc", "Fs", "sigma2")


def _rival_spread(bf: BranchFit, rival: dict) -> None:
    """A Stribeck drop that a rise ``rival`` fits as well as (:meth:`_Branch._drop_first`): the drop stands
    (the map is 003's drop, Fs >= Fc; a rise outside it that fits only as well is no evidence against it,
    one that fits clearly better is reported and flagged by :func:`.maps.physical_shape`), and the
    quantities the two share (:data:`SHARED_WITH_A_RISE`) carry their change to the rise in their standard
    errors (added in quadrature, as :func:`_delta_profile` does for the exponents that fit as well); one
    whose error so exceeds its value is not identifiable. The drop's speed and exponent keep their own
    errors: holding them as not identifiable read as a drop not seen (:func:`.validity.drop_spanned`) and
    took the break-away level, and with it the map that follows the points, out of the choice (the real
    screw drive 3: 1.3 % of the range against 2.3-2.9 % for the maps left). ``bf`` is changed in place."""
    for n in SHARED_WITH_A_RISE:
        se, v, r = bf.stderr.get(n), bf.values.get(n), rival.get(n)
        if n not in bf.free or se is None or v is None or r is None or r == v:
            continue
        sp = abs(r - v)
        bf.stderr[n] = math.hypot(se, sp)
        if n not in bf.reasons and bf.stderr[n] > abs(v):
            bf.reasons[n] = (f"moves by {sp:.3g} to a rise (Fs below Fc) that fits the points as well as this drop: "
                             "the data cannot tell the drop from a rise")


#: The parameters of a Stribeck drop whose error is no smaller than the delete-a-pair jackknife
#: (:func:`_pair_jackknife`), and the fewest groups of points that jackknife is taken over.
JACKKNIFE_PARAMS = ("Fs", "vs", "delta")
JACKKNIFE_MIN_GROUPS = 5
#: Two plateau points of opposite signs are a mirrored pair when their speeds differ by at most this share.
MIRROR_TOL = 0.1


def mirrored_groups(w) -> list[np.ndarray]:
    """The plateau points grouped by the speed they ran at: each point with the point of the other sign at
    its speed (within :data:`MIRROR_TOL`, nearest first, from the slowest), a point without one alone.
    A sweep runs each speed both ways, and what biases a plateau's mean beyond its batch-means error (a
    settling, the loop's transient after the move, the program around it) depends on the speed and the
    program, not the sign: such a pair's errors are one error, not two."""
    w = np.asarray(w, dtype=float)
    neg = [int(j) for j in np.flatnonzero(w < 0)]
    groups = []
    for i in (int(k) for k in np.flatnonzero(w > 0)[np.argsort(w[w > 0])]):
        j = min(neg, key=lambda j: abs(-w[j] - w[i])) if neg else None
        if j is not None and abs(-w[j] - w[i]) <= MIRROR_TOL * w[i]:
            groups.append(np.array([i, j]))
            neg.remove(j)
        else:
            groups.append(np.array([i]))
    return groups + [np.array([j]) for j in neg]


def _pair_jackknife(bw, bF, bse, bfixed: dict, scales, var_inflation: float, bf: BranchFit) -> None:
    """The Stribeck drop's parameters (:data:`JACKKNIFE_PARAMS`) with a standard error no smaller than the
    delete-a-group jackknife over the plateau points' mirrored pairs (:func:`mirrored_groups`): the branch
    refitted without each group from its optimum, the variance ``(G - 1) / G`` times the sum of squared
    changes about their mean. The drop is read from the few slowest plateaus; the Jacobian's error takes
    their batch-means errors as the whole of their error and the scatter of every point (``s^2``) as its
    scale, so a slow pair biased beyond its own error (both signs alike) goes into Fs, vs and delta with a
    leverage that neither measures. Foreign card (session 24): Fs outside two errors on 10 of 52 draws,
    by 0.1-0.3 % at errors of 0.02-0.14 %; the slowest pairs there sat 1.5-3 of their own errors low on
    both signs (244034, 244064). The same rule as the moving samples' jackknife floor
    (:func:`.samples.jackknife_errors`). ``bf`` is changed in place (stderr, the covariance's rows)."""
    names = [n for n in JACKKNIFE_PARAMS if n in bf.free and bf.stderr.get(n) is not None]
    groups = mirrored_groups(bw)
    if not names or len(groups) < JACKKNIFE_MIN_GROUPS:
        return
    th = []
    for g in groups:
        keep = np.ones(bw.shape[0], dtype=bool)
        keep[g] = False
        alt = fit_branch("stribeck", bw[keep], bF[keep], None if bse is None else bse[keep], dict(bfixed),
                         scales=scales, start=dict(bf.values), var_inflation=var_inflation)
        if not math.isfinite(alt.cost) or any(alt.values.get(n) is None for n in names):
            return
        th.append([alt.values[n] for n in names])
    th = np.asarray(th, dtype=float)
    G = th.shape[0]
    jse = np.sqrt((G - 1) / G * np.sum((th - th.mean(axis=0)) ** 2, axis=0))
    for n, js in zip(names, jse):
        se = bf.stderr[n]
        if not (js > se):
            continue
        j = bf.free.index(n)
        if bf.cov is not None and bf.cov[j, j] > 0:
            f = max(1.0, js / math.sqrt(bf.cov[j, j]))
            bf.cov[j, :] *= f
            bf.cov[:, j] *= f
        bf.stderr[n] = float(js)
        v = bf.values[n]
        if n not in bf.reasons and js > abs(v):
            bf.reasons[n] = (f"relative error {100 * js / abs(v):.0f} % (above 100 %) by the delete-a-pair "
                             "jackknife over the plateaus" if v else "relative error above 100 % by the "
                             "delete-a-pair jackknife over the plateaus")


def _shift_profile(base: str, bw, bF, bse, bfixed: dict, scales, var_inflation: float, bf: BranchFit,
                   shifts: list[np.ndarray]) -> None:
    """The points' common errors propagated into the parameters: each of ``shifts`` is the change of every
    point for one standard deviation of an independent direction of the rigid-body terms' error (inertia,
    gravity, offset, subtracted from the torque before the points are averaged). The branch is refitted on
    the shifted points and each parameter's change enters its standard error in quadrature (and its
    covariance); one whose error so exceeds its value is not identifiable. The points' own scatter does not
    show this error: it moves every point at once, smoothly along the angles the plateaus cover, and a
    sweep that climbs in speed as it travels turns a gravity error into a slope or a drop of the friction.
    ``bf`` is changed in place."""
    free = list(bf.free)
    D = []
    for dF in shifts:
        alt = fit_branch(base, bw, bF + dF, bse, dict(bfixed), scales=scales, start=dict(bf.values),
                         var_inflation=var_inflation)
        if not math.isfinite(alt.cost):
            continue
        D.append([alt.values[n] - bf.values[n] if alt.values.get(n) is not None else 0.0 for n in free])
    if not D:
        return
    D = np.asarray(D, dtype=float)
    extra = D.T @ D
    if bf.cov is not None and bf.cov.shape == extra.shape:
        bf.cov = bf.cov + extra
    for j, n in enumerate(free):
        se = bf.stderr.get(n)
        if se is None or extra[j, j] <= 0:
            continue
        bf.stderr[n] = math.hypot(se, math.sqrt(extra[j, j]))
        v = bf.values[n]
        if n not in bf.reasons and bf.stderr[n] > abs(v):
            bf.reasons[n] = (f"relative error {100 * bf.stderr[n] / abs(v):.0f} % (above 100 %) with the error of "
                             "the inertia, gravity and offset taken out of the torque" if v else
                             "relative error above 100 % with the error of the inertia, gravity and offset")


#: Stribeck exponents tried when the data do not pin delta down (000/003 hold it at 2; 1 is the exponential
#: of 001/004), and the profile's threshold: fits within this chi-square of the held fit are as good. The
#: grid spans the exponents real drives show (0.5 and below 1 are common: Armstrong-Helouvry's survey, the
#: issue-19 plants draw 0.5-2.5): a truth below 1 left out of it left Fs 10 % low with its error a third of
#: that (foreign card, seed 202121: delta 0.71, held at 2). Below 1 a map with a cusp at zero speed can carry
#: the break-away level far above the slowest plateau (0.75 put the hydraulic plant's Fs at 289 +- 372):
#: where such an exponent fits as well, that is what the data cannot rule out, and the level's error or
#: :func:`.validity._drop_in_view_at_every_exponent` says so.
DELTA_GRID = (0.5, 0.75, 1.0, 1.5, 3.0)
DELTA_CHI2 = 4.0


def _delta_profile(bw, bF, bse, bfixed: dict, scales, var_inflation: float, bf: BranchFit) -> None:
    """With delta held at 2 because the data cannot pin it, the other parameters are conditional on that
    choice: refitted at each exponent of :data:`DELTA_GRID`, those fits whose chi-square is within
    :data:`DELTA_CHI2` of the held one are as consistent with the data, and the largest change of each
    parameter among them enters its standard error (added in quadrature); one whose error so exceeds its
    value is not identifiable. ``bf`` is changed in place."""
    dof = max(len(bw) - len(bf.free), 1)
    s2 = 2.0 * bf.cost / dof
    if not (s2 > 0 and math.isfinite(s2)):
        return
    spread: dict[str, float] = {n: 0.0 for n in bf.free}
    for d in DELTA_GRID:
        fx = dict(bfixed, delta=d)
        alt = fit_branch("stribeck", bw, bF, bse, fx, scales=scales, start=dict(bf.values, delta=d),
                         var_inflation=var_inflation)
        _widen(spread, bf, alt, s2)
    _add_spread(bf, spread, lambda sp: (
        f"depends on the Stribeck exponent, which the data do not pin down (held at 2): it moves by {sp:.3g} "
        f"over exponents {DELTA_GRID[0]}-{DELTA_GRID[-1]} that fit as well"))


def _widen(spread: dict[str, float], bf: BranchFit, alt: BranchFit, s2: float) -> None:
    """Each parameter's largest change (``spread``, in place) among the refits ``alt`` that fit as well as
    ``bf`` (chi-square within :data:`DELTA_CHI2`)."""
    if not math.isfinite(alt.cost) or 2.0 * (alt.cost - bf.cost) / s2 > DELTA_CHI2:
        return
    for n in spread:
        if alt.values.get(n) is not None and bf.values.get(n) is not None:
            spread[n] = max(spread[n], abs(alt.values[n] - bf.values[n]))


def _add_spread(bf: BranchFit, spread: dict[str, float], reason) -> None:
    """The spread of each parameter added to its standard error in quadrature; ``reason(spread)`` where the
    error then exceeds the value and no reason was given yet."""
    for n, sp in spread.items():
        se = bf.stderr.get(n)
        if sp <= 0 or se is None:
            continue
        bf.stderr[n] = math.hypot(se, sp)
        if n not in bf.reasons and bf.stderr[n] > abs(bf.values[n]):
            bf.reasons[n] = reason(sp)


def _free_delta_profile(bw, bF, bse, bfixed: dict, scales, var_inflation: float, bf: BranchFit) -> None:
    """With a free Stribeck exponent the Jacobian's errors are those of a map linear in delta; the
    break-away level and the drop's speed are not (the level at zero speed extrapolated from the slowest
    plateaus moves faster with the exponent the further the drop's top lies below them). The branch is
    refitted with delta held at one and two of its standard errors either side (within the table's
    bounds); each refit within :data:`DELTA_CHI2` of chi-square of the free fit gives each parameter's
    change over that many standard errors, and the largest such change per standard error is the
    parameter's standard error when it is larger than the Jacobian's (a profile error). Foreign card: a
    sweep whose slowest useful plateau held a third of the drop gave delta 1.73 +- 0.41 (truth 1.13) and
    Fs 0.02925 +- 0.00051 against 0.03078 (3 errors; at delta 1.0, 3.9 of chi-square worse, Fs is 0.0320).
    ``bf`` is changed in place."""
    dof = max(len(bw) - len(bf.free), 1)
    s2 = 2.0 * bf.cost / dof
    d0, sd = bf.values.get("delta"), bf.stderr.get("delta")
    if not (s2 > 0 and math.isfinite(s2)) or d0 is None or not sd or not math.isfinite(sd):
        return
    prm = next(p for p in sm.STATIC_MAPS["stribeck"].table if p.name == "delta")
    per_se: dict[str, float] = {n: 0.0 for n in bf.free if n != "delta"}
    for m in (1.0, 2.0):
        for d in (d0 - m * sd, d0 + m * sd):
            if not prm.lower <= d <= prm.upper:
                continue
            alt = fit_branch("stribeck", bw, bF, bse, dict(bfixed, delta=d), scales=scales,
                             start=dict(bf.values, delta=d), var_inflation=var_inflation)
            if not math.isfinite(alt.cost) or 2.0 * (alt.cost - bf.cost) / s2 > DELTA_CHI2:
                continue
            for n in per_se:
                if alt.values.get(n) is not None and bf.values.get(n) is not None:
                    per_se[n] = max(per_se[n], abs(alt.values[n] - bf.values[n]) / m)
    for n, sp in per_se.items():
        se = bf.stderr.get(n)
        if se is None or sp <= se:
            continue
        bf.stderr[n] = sp
        v = bf.values[n]
        if n not in bf.reasons and sp > abs(v):
            bf.reasons[n] = (f"relative error {100 * sp / abs(v):.0f} % (above 100 %) over the Stribeck exponents "
                             "that fit as well")


def _degenerate_drop(bf: BranchFit, bfixed: dict, shapeless: dict[str, str], suf: str, scales) -> bool:
    """Whether a Stribeck branch's drop is degenerate: a shape parameter held where the fit put it because
    the data could not place it (``shapeless``), or a free one (Fs, vs, delta) at a bound of the fit (the
    selection's rule, :func:`.select.shape_only`, does not take such a map)."""
    if any(n + suf in shapeless for n in DROP_SHAPE_NAMES):
        return True
    table = sm.STATIC_MAPS["stribeck"].table
    lo, hi, _, _ = scaled_table(table, *scales)
    for k, prm in enumerate(table):
        v = bf.values.get(prm.name)
        if prm.name not in DROP_SHAPE_NAMES or prm.name in bfixed or v is None:
            continue
        tol = 1e-6 * (hi[k] - lo[k]) if math.isfinite(hi[k] - lo[k]) else 1e-6 * max(1.0, abs(v))
        if any(math.isfinite(b) and abs(v - b) <= tol for b in (lo[k], hi[k])):
            return True
    return False


#: A Stribeck drop's shape parameters; and the profile of a degenerate drop (:func:`_shape_profile`): its
#: speed held at this many values log-spaced from a sixteenth of the slowest point's speed to the fastest,
#: each at every exponent of :data:`DELTA_GRID`.
DROP_SHAPE_NAMES = ("Fs", "vs", "delta")
SHAPE_SPEEDS = 10


def _shape_profile(bw, bF, bse, bfixed: dict, scales, var_inflation: float, bf: BranchFit) -> None:
    """A degenerate drop (:func:`_degenerate_drop`: a break-away at its bound, a speed held where the fit
    put it) fixes the level and slope only through the shape the fit happened to end at: with the drop's
    speed and exponent held at every pair of a grid over the points' speeds (:data:`SHAPE_SPEEDS`) and
    :data:`DELTA_GRID`, the fits within :data:`DELTA_CHI2` of chi-square of this one are as consistent with
    the data, and each free parameter's largest change among them enters its standard error (added in
    quadrature, as :func:`_delta_profile` does) for the level it drops to and the slope (the break-away
    level is the drop's own: :func:`.validity.drop_spanned`); one whose error so exceeds its value is not
    identifiable.
    The drop-free map's level (:func:`.validity.drop_spanned`) is one such shape only (tests: the tail of a
    drop below the slowest plateau, Fc's error doubled to cover the truth). Where every shape that fits as
    well gives the same level, the level stands: foreign 204132's Fc 87.59 +- 0.58 against 90.36 (the
    drop-free map 87.70) is not the shape's error. ``bf`` is changed in place."""
    dof = max(len(bw) - len(bf.free), 1)
    s2 = 2.0 * bf.cost / dof
    v = np.abs(np.asarray(bw, dtype=float))
    v = v[np.isfinite(v) & (v > 0)]
    if not (s2 > 0 and math.isfinite(s2)) or v.size == 0 or not v.min() / 16.0 > 0:  # (a subnormal speed)
        return
    table = sm.STATIC_MAPS["stribeck"].table
    lo, hi, _, _ = scaled_table(table, *scales)
    k = [p.name for p in table].index("vs")
    speeds = np.clip(np.geomspace(v.min() / 16.0, v.max(), SHAPE_SPEEDS), lo[k], hi[k])
    keep = [n for n in bf.free if n not in DROP_SHAPE_NAMES]  # the drop's own level has its own rules
    spread = {n: 0.0 for n in keep}
    for vs in speeds:
        for d in DELTA_GRID:
            fx = dict(bfixed, vs=float(vs), delta=d)
            alt = fit_branch("stribeck", bw, bF, bse, fx, scales=scales, start=dict(bf.values, vs=float(vs), delta=d),
                             var_inflation=var_inflation)
            _widen(spread, bf, alt, s2)
    _add_spread(bf, spread, lambda sp: (f"depends on the shape of a drop the fit could not place: it moves by "
                                        f"{sp:.3g} over drop speeds and exponents that fit as well"))


def _branch_params(smap, suf: str, bf: BranchFit, shapeless: dict[str, str], axis: str, scales
                   ) -> dict[str, ParamEstimate]:
    """The parameter estimates of a fitted branch (suffixed names), each with the bounds the optimiser
    had (the map's table scaled to the data, ``scales`` = (F0, w0))."""
    params = {}
    lo, hi, _, _ = scaled_table(smap.table, *scales)
    for k, prm in enumerate(smap.table):
        nm = prm.name
        unit = unit_of(prm.dim, axis)
        if nm + suf in shapeless:
            params[nm + suf] = ParamEstimate(nm + suf, bf.fixed[nm], None, unit, False,
                                             shapeless[nm + suf], fixed=True)
        elif nm in bf.fixed:
            params[nm + suf] = ParamEstimate(nm + suf, bf.fixed[nm], None, unit, True,
                                             "held fixed", fixed=True)
        else:
            r = bf.reasons.get(nm, "")
            params[nm + suf] = ParamEstimate(nm + suf, bf.values[nm], bf.stderr[nm], unit, not r, r)
        params[nm + suf].bounds = (float(lo[k]), float(hi[k]))
    return params
